"""Typed configuration: defaults, overlays, overrides and their errors."""

import pytest

from ptam.config import load_config
from ptam.errors import ConfigError


def test_defaults_carry_the_papers_values():
    cfg = load_config()
    assert cfg.image.levels == 4
    assert cfg.image.fast_thresholds == [10, 15, 15, 10]
    assert cfg.tracker.max_patches == 1000 and cfg.tracker.coarse_points == 50
    assert cfg.tracker.irls_iterations == 10


def test_every_default_is_commented_with_its_source():
    from ptam.resources import resource_path

    for line in resource_path("configs/default.yaml").read_text().splitlines():
        stripped = line.strip()
        if stripped and not stripped.startswith("#") and not stripped.endswith(":"):
            assert "#" in stripped, f"default without a source comment: {stripped}"


def test_overlay_file_and_set(tmp_path):
    f = tmp_path / "mine.yaml"
    f.write_text("tracker:\n  max_patches: 400\n  quality_good: 0.25\n")
    cfg = load_config([str(f)], ["tracker.max_patches=300", "image.fast_thresholds=[9, 9, 9, 9]"])
    assert cfg.tracker.max_patches == 300
    assert cfg.tracker.quality_good == 0.25
    assert cfg.image.fast_thresholds == [9, 9, 9, 9]
    assert isinstance(load_config(overrides=["tracker.quality_good=1"]).tracker.quality_good, float)


@pytest.mark.parametrize(
    "override, message",
    [
        ("tracker.max_patchs=3", r"unknown config key 'tracker.max_patchs' \(did you mean 'tracker.max_patches'\?\)"),
        ("trackr.max_patches=3", r"unknown config section 'trackr' \(did you mean 'tracker'\?\)"),
        ("tracker.max_patches=many", r"tracker.max_patches must be int"),
        ("tracker.max_patches=1.5", r"tracker.max_patches must be int"),
        ("image.fast_thresholds=[1, a]", r"image.fast_thresholds\[1\] must be int"),
        ("system.mode=fast", r"system.mode must be one of"),
        ("tracker", r"--set expects section.key=value"),
    ],
)
def test_bad_overrides(override, message):
    with pytest.raises(ConfigError, match=message):
        load_config(overrides=[override])


def test_bad_files(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_config([str(tmp_path / "none.yaml")])
    bad = tmp_path / "bad.yaml"
    bad.write_text("tracker: {max_patches: 3, nope: 1}\n")
    with pytest.raises(ConfigError, match="unknown config key 'tracker.nope'"):
        load_config([str(bad)])
