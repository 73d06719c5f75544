"""MapMaker pieces on a ground-truth map: tracker feedback marks bad points (PTAM code HandleBadPoints)."""

import dataclasses

import numpy as np

from ptam.bench.gt_map import build_gt_map
from ptam.config import load_config
from ptam.mapping.map_maker import MapMaker
from ptam.synthetic import load_scene


def test_points_the_tracker_keeps_rejecting_become_bad():
    cfg = load_config()
    scene = load_scene("two_wall_short")
    mm = MapMaker(scene.camera, cfg, build_gt_map(scene, cfg, kf_every=20, max_points=200, frames=range(0, 21)))
    n_meas = mm.map.n_measurements
    limit = cfg.mapper.bad_point_min_outliers
    rejected, disputed, fine = 3, 4, 5
    for _ in range(limit + 1):
        mm.report_tracking(np.array([fine, disputed]), np.array([rejected, disputed]))
    mm.report_tracking(np.array([disputed]), np.array([], np.int64))  # disputed: one more inlier than outlier
    assert mm.step() is False  # nothing else to do, but the feedback was handled
    bad = mm.snapshot.bad
    assert bad[rejected] and not bad[disputed] and not bad[fine]
    assert bad.sum() == 1
    assert mm.map.n_measurements == n_meas - 1  # its one (source-keyframe) measurement is gone
    assert not (mm.map.meas_pt == rejected).any()


def _map_with_wrong_measurements(scene, cfg, n_wrong: int):
    """Keyframes at frames 0, 20, 40 and their true poses but keyframe 2's, 1 mm off; every point also measured in
    keyframe 1 where it projects, ``n_wrong`` of those 25 px off. Returns the map and the points measured wrongly."""
    m = build_gt_map(scene, cfg, kf_every=20, max_points=200, frames=range(0, 41))
    T = m.kf_T_cw[1]
    Xc = m.X @ T[:3, :3].T + T[:3, 3]
    uv = scene.camera.project(Xc)
    ids = np.flatnonzero(scene.camera.valid(Xc) & scene.camera.in_image(uv, 8.0) & (m.source_kf != 1))
    uv[ids[:n_wrong], 0] += 25.0
    m.add_measurements(np.ones(len(ids), np.int64), ids, uv[ids], np.zeros(len(ids), np.int64))
    T2 = m.kf_T_cw[2].copy()
    T2[0, 3] += 0.001  # 1 mm: a first step to take
    m.set_poses([2], T2[None])
    return m, ids[:n_wrong]


def test_outliers_of_a_ba_stopped_at_the_iteration_limit_wait_for_one_that_converges():
    scene = load_scene("two_wall_short")
    stopped = {"bundle.max_iterations": 1, "bundle.converge_squared_update": 0.0}
    for overrides, converged, acted_on in (
        ({}, True, True),  # converged: PTAM §6.4, the wrong ones' points (two measurements each) are bad
        (stopped, False, False),  # stopped at the limit: its zero weights are provisional
        ({**stopped, "mapper.unfinished_ba_outliers": True}, False, True),  # PTAM code acts on them anyway
    ):
        mm, wrong, n_meas = _adjusted_once(scene, load_config().replace(**overrides))
        assert mm.stats["global_ba"][-1][2] == converged
        bad = np.flatnonzero(mm.map.bad)
        if acted_on:
            assert np.array_equal(bad, np.sort(wrong))
        else:
            assert len(bad) == 0 and mm.map.n_measurements == n_meas


def test_outliers_left_by_a_stopped_ba_are_acted_on_when_the_next_stopped_one_flags_as_many():
    """Left while each stopped run flags fewer than the last; a run flagging as many is getting nowhere, and left
    for ever its outliers would have a mapper with nothing else to do repeat it without end."""
    scene = load_scene("two_wall_short")
    cfg = load_config().replace(**{"bundle.max_iterations": 1, "bundle.converge_squared_update": 0.0})
    mm, wrong, n_meas = _adjusted_once(scene, cfg)
    assert not mm.stats["global_ba"][-1][2] and not mm.map.bad.any() and mm.map.n_measurements == n_meas
    mm.bundle_adjust(recent=False)  # stopped again, the same 10 measurements flagged
    assert not mm.stats["global_ba"][-1][2]
    assert np.array_equal(np.flatnonzero(mm.map.bad), np.sort(wrong))


def test_stopped_bas_flagging_fewer_each_time_leave_their_outliers():
    scene = load_scene("two_wall_short")
    cfg = load_config().replace(**{"bundle.max_iterations": 1, "bundle.converge_squared_update": 0.0})
    flagged = iter((10, 9))

    def fewer(adjust):
        def run(*a, **k):
            res = adjust(*a, **k)
            return dataclasses.replace(res, outliers=res.outliers[: next(flagged)])

        return run

    mm, _, n_meas = _adjusted_once(scene, cfg, wrap=fewer)
    mm.bundle_adjust(recent=False)
    assert not mm.map.bad.any() and mm.map.n_measurements == n_meas


def test_outliers_of_a_ba_that_stopped_without_moving_are_final():
    """Stopped at the limit with every step rejected, the BA ends where it began: the next one would repeat it."""
    scene = load_scene("two_wall_short")
    cfg = load_config().replace(**{"bundle.max_iterations": 1, "bundle.converge_squared_update": 0.0})

    def unmoved(adjust):
        return lambda *a, **k: dataclasses.replace(adjust(*a, **k), accepted=0)

    mm, wrong, _ = _adjusted_once(scene, cfg, wrap=unmoved)
    assert not mm.stats["global_ba"][-1][2]
    assert np.array_equal(np.flatnonzero(mm.map.bad), np.sort(wrong))


def _adjusted_once(scene, cfg, n_wrong: int = 10, wrap=None):
    """One global BA of the map of ``_map_with_wrong_measurements``: (mapper, the points measured wrongly, the
    measurement count before). ``wrap``: applied to the mapper's ``Bundle.adjust``."""
    m, wrong = _map_with_wrong_measurements(scene, cfg, n_wrong)
    n_meas = m.n_measurements
    mm = MapMaker(scene.camera, cfg, m)
    if wrap is not None:
        mm.bundle.adjust = wrap(mm.bundle.adjust)
    mm.bundle_adjust(recent=False)
    return mm, wrong, n_meas


def _map_with_panorama_keyframe(scene, cfg, offset_m: float, gained_depth: bool, old_points: bool = True):
    """Keyframes at frames 0, 20, 40 at their true poses, keyframe 1 flagged panorama and ``offset_m`` off along x
    (a pose tracked under [R|0]); every point also measured, exactly, in keyframe 1 where it projects. Keyframe 1's
    own points are its rays that gained depth, or (``gained_depth`` false) bad: it then measures old points alone;
    ``old_points`` false: keyframes 0 and 2 are panorama keyframes too, so that it measures gained rays alone."""
    m = build_gt_map(scene, cfg, kf_every=20, max_points=200, frames=range(0, 41))
    if not gained_depth:
        m.mark_bad(np.flatnonzero(m.source_kf == 1))
    T = m.kf_T_cw[1].copy()
    Xc = m.X @ T[:3, :3].T + T[:3, 3]
    uv = scene.camera.project(Xc)
    ids = np.flatnonzero(scene.camera.valid(Xc) & scene.camera.in_image(uv, 8.0) & (m.source_kf != 1))
    m.add_measurements(np.ones(len(ids), np.int64), ids, uv[ids], np.zeros(len(ids), np.int64))
    for k in (1,) if old_points else (0, 1, 2):
        m.keyframes[k] = dataclasses.replace(m.keyframes[k], panorama=True)
    T[0, 3] += offset_m
    m.set_poses([1], T[None])
    return m


def _centre_error(C, C_true) -> float:
    """Keyframe 1's centre error (m) in the map's scale measured by keyframes 0 (fixed) and 2."""
    s = np.linalg.norm(C_true[2] - C_true[0]) / np.linalg.norm(C[2] - C[0])
    return float(np.linalg.norm(C_true[0] + s * (C[1] - C[0]) - C_true[1]))


def test_a_panorama_keyframe_that_measures_3d_points_is_adjusted_with_them():
    """Gauglitz §5.2 adjusts SfM groups; with ``model_selection.adjust_panorama_keyframes`` a panorama keyframe
    enough of whose rays gained depth (§4.3) and which measures enough old points is adjusted with the group; one
    short of either keeps its pose."""
    scene = load_scene("two_wall_short")
    for adjust, min_points, gained, old, moved in (
        (True, 10, True, True, True),
        (False, 10, True, True, False),  # Gauglitz §5.2
        (True, 10**6, True, True, False),  # too few of its rays gained depth
        (True, 10, False, True, False),  # old points alone (174 of them) do not make it SfM
        (True, 10, True, False, False),  # gained rays alone (its 16, the others' 174) do not tie it to SfM
    ):
        cfg = load_config().replace(
            **{"model_selection.adjust_panorama_keyframes": adjust, "model_selection.min_sfm_points": min_points}
        )
        m = _map_with_panorama_keyframe(scene, cfg, 0.005, gained, old)  # 5 mm at 3 m: about 1 px
        start = m.kf_T_cw[1].copy()
        mm = MapMaker(scene.camera, cfg, m)
        mm.bundle_adjust(recent=False)
        assert mm.stats["global_ba"][-1][2]  # converged
        error_mm = 1e3 * _centre_error(mm.map.camera_centres, scene.poses_T_wc[[0, 20, 40], :3, 3])
        if moved:
            assert error_mm < 0.5  # measured 0.005 mm
        else:
            # Held: its rotation as tracked, its centre as far off as before (the BA's scale hold moved it a little).
            assert np.array_equal(mm.map.kf_T_cw[1][:3, :3], start[:3, :3]) and error_mm > 3.0
