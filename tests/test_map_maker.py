"""MapMaker pieces on a ground-truth map: tracker feedback marks bad points (PTAM code HandleBadPoints)."""

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
