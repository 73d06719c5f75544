"""Global BA's free scale (mapping/gauge.py): holding it changes no residual, and keeps a map with edgelets from
wandering in scale while it grows (the online poses carry the scale of their moment)."""

import numpy as np
import pytest

from ptam.config import default_config
from ptam.geometry import se3
from ptam.image.pyramid import Pyramid
from ptam.map.keyframe import KeyFrame
from ptam.map.map import SRC_ROOT, Map
from ptam.mapping.gauge import hold_scale
from tests.support.cameras import CAMERAS

CFG = default_config()


def _map(rng):
    cam = CAMERAS["fov"]
    blank = Pyramid.build(np.zeros((cam.height, cam.width), np.uint8), CFG.image)
    m = Map()
    for i in range(5):
        T_cw = se3.exp(np.r_[rng.normal(0, 0.2, 3), rng.normal(0, 0.05, 3)])
        m.add_keyframe(KeyFrame(i, blank, 2.0, 0.3), T_cw)
    X = rng.uniform(-1, 1, (300, 3)) + [0.0, 0.0, 2.5]
    ids = m.add_points(X, np.broadcast_to([0.0, 0.0, -1.0], (300, 3)), 0, 0, np.zeros((300, 2)))
    m.add_measurements(0, ids, np.zeros((300, 2)), 0, SRC_ROOT)
    return cam, m


def _projections(cam, m):
    return np.stack([cam.project(se3.transform(T, m.X)) for T in m.kf_T_cw])


def test_the_scale_a_global_ba_gave_is_undone_without_changing_a_residual():
    cam, m = _map(np.random.default_rng(2))
    before = m.camera_centres.copy()
    uv = _projections(cam, m)
    c0 = before[0]
    T = np.eye(4)
    T[:3, 3] = (1.0 - 1.006) * c0
    m.transform(T, 1.006)  # what a step along the free scale does: everything 0.6 % larger about keyframe 0
    factor = hold_scale(m, before)
    assert factor == pytest.approx(1.0 / 1.006, rel=1e-12)
    assert np.allclose(m.camera_centres, before, atol=1e-12)
    assert np.allclose(_projections(cam, m), uv, atol=1e-9)  # a similarity about keyframe 0 moves no pixel


def test_new_keyframes_do_not_vote():
    """Only the keyframes that existed before the adjustment set the scale (the newest has no old position)."""
    cam, m = _map(np.random.default_rng(3))
    before = m.camera_centres[:4].copy()
    assert hold_scale(m, before) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.slow
def test_edgelets_no_longer_move_the_scale_of_a_growing_map():
    """desk_bricks, sync: with edgelets (Agility §4.4) every global BA moved the map's free scale by up to 0.6 %,
    and the tracked poses carried it (4.6 mm ATE against 0.4 mm with points alone, measured); held, edgelets are
    as accurate as points alone. The wander shows on the map of one target keyframe per edgelet candidate
    (``edgelets.aperture_retry=false``); the default map, whose second targets add desk_bricks' horizontal joints
    seen over a second baseline, damps it (0.8 mm with a free scale, measured) and is held as well."""
    import dataclasses

    from ptam.bench.accuracy import criteria
    from ptam.eval.score import score_trajectory
    from ptam.system.core import run_dataset
    from ptam.vocabulary import RunMode
    from tests.support import sequence

    d = sequence("desk_bricks")

    def ate_mm(edgelets: bool, hold: bool, retry: bool = True) -> float:
        cfg = dataclasses.replace(
            CFG,
            edgelets=dataclasses.replace(CFG.edgelets, enabled=edgelets, aperture_retry=retry),
            bundle=dataclasses.replace(CFG.bundle, hold_scale=hold),
        )
        run = run_dataset(d, cfg, mode=RunMode.SYNC)
        return 1e3 * score_trajectory(d / "groundtruth.txt", run.trajectory, criteria=criteria(cfg)).ate_rmse_m

    points, edgelets = ate_mm(False, True), ate_mm(True, True)
    one_target, free = ate_mm(True, True, retry=False), ate_mm(True, False, retry=False)
    print(
        f"desk_bricks ATE: points {points:.2f} mm, edgelets {edgelets:.2f} mm; one target keyframe: held "
        f"{one_target:.2f} mm, free scale {free:.2f} mm"
    )
    assert edgelets <= 1.25 * points + 0.05 and one_target <= 1.25 * points + 0.05
    assert free >= 3.0 * one_target
