"""Map files store edgelets (format version 3, Agility §4): a map with edgelets and their measurements reloads
exactly, versions 1 and 2 still load (without edgelets), the mapper rebuilds the visibility tables (§5.2) of a
loaded map, and corrupt edgelet members are refused with one InputError line."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ptam.camera import camera_from_dict
from ptam.edgelet import Edgelets, table_blurs
from ptam.errors import InputError
from ptam.map.map_file import VERSION, load_map, save_map
from ptam.mapping.map_maker import MapMaker
from tests.support import config
from tests.test_map_file_validation import CAMERA, N_KF, H, W, arrays, good, rewritten  # noqa: F401

N_E = 12
EDGELET_COLUMNS = ("centre", "direction", "normal", "source_kf", "bad", "meas_kf", "meas_edgelet", "meas_a", "meas_b")


@pytest.fixture(scope="module")
def with_edgelets(good, tmp_path_factory):  # noqa: F811
    """The validation tests' good map plus 12 edgelets (one bad), each measured in two keyframes."""
    rng = np.random.default_rng(1)
    m = load_map(good, config().image).map
    ed = Edgelets(
        np.c_[rng.uniform(-0.5, 0.5, (N_E, 2)), rng.uniform(1.5, 2.5, N_E)],
        rng.normal(size=(N_E, 3)),
        rng.normal(size=(N_E, 3)),
    ).orthonormalised()
    ids = m.add_edgelets(ed.centre, ed.direction, ed.normal, rng.integers(0, N_KF, N_E))
    kf = np.r_[np.zeros(N_E, int), np.ones(N_E, int)]
    ang = rng.uniform(0, np.pi, 2 * N_E)
    b = np.c_[np.cos(ang), np.sin(ang)]
    m.add_edgelet_measurements(kf, np.r_[ids, ids], rng.uniform([5, 5], [W - 6, H - 6], (2 * N_E, 2)), b)
    m.mark_edgelets_bad([4])
    path = tmp_path_factory.mktemp("maps") / "edgelets.npz"
    save_map(path, m.snapshot(), camera_from_dict(CAMERA), config().image.levels)
    return path, m.snapshot()


def test_edgelets_round_trip_exactly(with_edgelets):
    path, snap = with_edgelets
    assert VERSION == 4 and int(arrays(path)["version"]) == 4
    again = load_map(path, config().image).map.snapshot()
    for c in EDGELET_COLUMNS:
        a, b = getattr(snap, f"edgelet_{c}"), getattr(again, f"edgelet_{c}")
        assert a.dtype == b.dtype and np.array_equal(a, b), c
    assert len(again.edgelet_meas_kf) == 2 * (N_E - 1) and again.edgelet_bad.sum() == 1
    assert np.array_equal(snap.X, again.X) and np.array_equal(snap.meas_xy, again.meas_xy)


@pytest.mark.parametrize("version", [1, 2])
def test_older_versions_load_without_edgelets(with_edgelets, tmp_path, version):
    path, snap = with_edgelets
    a = {k: v for k, v in arrays(path).items() if not k.startswith("edgelet_") and k != "kf_part"}
    if version == 1:
        a = {k: v for k, v in a.items() if k not in ("ray", "kf_panorama")}
    np.savez_compressed(tmp_path / "old.npz", **{**a, "version": np.array(version)})
    old = load_map(tmp_path / "old.npz", config().image).map.snapshot()
    assert old.n_points == snap.n_points and len(old.edgelet_centre) == 0 and len(old.edgelet_meas_kf) == 0
    assert old.edgelet_centre.shape == (0, 3) and old.edgelet_meas_a.shape == (0, 2)


def test_a_version_3_file_loads_with_every_keyframe_the_maps_own(with_edgelets, tmp_path):
    """Version 4 added each keyframe's merged-track part (Gauglitz §5.3); a version 3 map has none: all part 0."""
    path, snap = with_edgelets
    a = {k: v for k, v in arrays(path).items() if k != "kf_part"}
    np.savez_compressed(tmp_path / "v3.npz", **{**a, "version": np.array(3)})
    old = load_map(tmp_path / "v3.npz", config().image).map.snapshot()
    assert [k.part for k in old.keyframes] == [0] * snap.n_keyframes
    assert np.array_equal(old.edgelet_centre, snap.edgelet_centre)


def test_a_version_3_file_without_edgelets_is_incomplete(with_edgelets, tmp_path):
    path, _ = with_edgelets
    p = rewritten(path, tmp_path, lambda a: a.pop("edgelet_meas_b"))
    with pytest.raises(InputError, match="incomplete: no 'edgelet_meas_b'"):
        load_map(p, config().image)


def test_the_mapper_rebuilds_the_visibility_tables(with_edgelets):
    path, snap = with_edgelets
    cfg = config()
    loaded = load_map(path, cfg.image)
    assert not loaded.map.edgelets.tables
    on = dataclasses.replace(cfg, edgelets=dataclasses.replace(cfg.edgelets, enabled=True))
    tables = MapMaker(loaded.camera, on, loaded.map).snapshot.edgelet_tables
    assert set(tables) == {0, 1}
    for k, (ids, visible, r_search, t_min, max_blur) in tables.items():
        assert np.array_equal(np.sort(ids), np.sort(snap.edgelet_meas_edgelet[snap.edgelet_meas_kf == k]))
        assert visible.shape == r_search.shape == t_min.shape == (len(ids), len(table_blurs(on.edgelets)))
        assert max_blur.shape == (len(ids),)


def _poke(name, index, value):
    def change(a):
        a[name] = a[name].copy()
        a[name][index] = value

    return change


def _duplicate(a):
    for k in ("edgelet_meas_kf", "edgelet_meas_edgelet", "edgelet_meas_a", "edgelet_meas_b"):
        a[k] = np.concatenate([a[k], a[k][:1]])


CASES = [
    ("NaN centre", _poke("edgelet_centre", (2, 1), np.nan), r"'edgelet_centre\[2, 1\]' is nan"),
    ("long direction", _poke("edgelet_direction", 3, [0.0, 2.0, 0.0]), r"'edgelet_direction\[3\]' = .* unit vector"),
    (
        "skew normal",
        lambda a: a.__setitem__("edgelet_normal", a["edgelet_direction"].copy()),
        r"'edgelet_normal\[0\]' = .* must be perpendicular to 'edgelet_direction'",
    ),
    ("line direction", _poke("edgelet_meas_b", 5, [0.3, 0.3]), r"'edgelet_meas_b\[5\]' = .* unit vector"),
    ("edgelet index", _poke("edgelet_meas_edgelet", 0, N_E), rf"edgelet index out of range \[0, {N_E}\)"),
    ("source keyframe", _poke("edgelet_source_kf", 1, N_KF), rf"keyframe index out of range \[0, {N_KF}\)"),
    ("line outside", _poke("edgelet_meas_a", 2, [W + 5.0, 3.0]), rf"'edgelet_meas_a\[2\]' = .* outside the {W}x{H}"),
    ("duplicate", _duplicate, r"'edgelet_meas_kf'/'edgelet_meas_edgelet': keyframe 0 measures edgelet \d+ more"),
    (
        "short column",
        lambda a: a.__setitem__("edgelet_bad", a["edgelet_bad"][:-1]),
        rf"'edgelet_bad' has shape \({N_E - 1},\), expected \({N_E},\)",
    ),
    (
        "int flags",
        lambda a: a.__setitem__("edgelet_bad", a["edgelet_bad"].astype(np.int8)),
        r"'edgelet_bad' must be a bool array",
    ),
]


@pytest.mark.parametrize("case, change, message", CASES, ids=[c[0] for c in CASES])
def test_corrupt_edgelet_members_are_refused(with_edgelets, tmp_path, case, change, message):
    path = rewritten(with_edgelets[0], tmp_path, change)
    with pytest.raises(InputError, match=rf"^map file {path}:? .*{message}") as e:
        load_map(path, config().image)
    assert "\n" not in str(e.value)
