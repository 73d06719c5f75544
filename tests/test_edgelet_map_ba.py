"""Agility §4.4 in the mapper: local and global bundle adjustment move the map's edgelets when edgelets are on,
and outlying edgelet measurements are dropped, or their edgelets marked bad, as points' are (PTAM §6.4)."""

import dataclasses

import numpy as np
import pytest

from ptam.edgelet import Edgelets
from ptam.image.pyramid import Pyramid
from ptam.map.keyframe import KeyFrame
from ptam.map.map import SRC_ROOT, Map
from ptam.mapping.local_ba import local_sets
from ptam.mapping.map_maker import MapMaker
from tests.support import config
from tests.support.ba_problems import edgelet_errors, synthetic_edgelets, synthetic_workspace_problem


@pytest.fixture(scope="module")
def problem():
    prob = synthetic_workspace_problem(10, 300, seed=8, outlier_fraction=0.0)
    return prob, synthetic_edgelets(prob, 100, seed=9, gross_fraction=0.03)


def _mapper(problem, enabled: bool) -> MapMaker:
    """A map of the problem: keyframes 1.. and edgelets at the perturbed start, keyframe 0 and points at the
    truth; each edgelet's source keyframe is the first that measures it."""
    prob, eb = problem
    cfg = config()
    cfg = dataclasses.replace(cfg, edgelets=dataclasses.replace(cfg.edgelets, enabled=enabled))
    blank = Pyramid.build(np.zeros((prob.camera.height, prob.camera.width), np.uint8), cfg.image)
    m = Map()
    poses = prob.poses_init.copy()
    poses[0] = prob.poses_true[0]
    for i, T in enumerate(poses):
        m.add_keyframe(KeyFrame(i, blank, 3.0, 1.0), T)
    X = prob.points_true
    m.add_points(X, np.tile([0.0, 0.0, -1.0], (len(X), 1)), 0, 0, np.zeros((len(X), 2)))
    m.add_measurements(prob.meas_kf, prob.meas_pt, prob.meas_xy, prob.meas_level, SRC_ROOT)
    first = np.full(len(eb.init), len(poses))
    np.minimum.at(first, eb.obs.edgelet, eb.obs.kf)
    m.add_edgelets(eb.init.centre, eb.init.direction, eb.init.normal, first)
    m.add_edgelet_measurements(eb.obs.kf, eb.obs.edgelet, eb.obs.a, eb.obs.b)
    return MapMaker(prob.camera, cfg, m)


def test_global_adjustment_moves_edgelets_and_drops_outliers(problem):
    prob, eb = problem
    mm = _mapper(problem, enabled=True)
    m = mm.map
    mm.bundle_adjust(recent=False)
    good = ~m.edgelets.view("bad")
    d, a = edgelet_errors(Edgelets(*(m.edgelets.view(k) for k in ("centre", "direction", "normal"))), eb.truth)
    d0, a0 = edgelet_errors(eb.init, eb.truth)
    # 3 cm / 3° at the start; at the end the estimator's error plus the map's gauge drift (one keyframe fixed, the
    # others 4-9 mm from the truth).
    assert np.median(d0) > 25.0 and np.median(a0) > 2.5
    assert np.median(d[good]) < 8.0 and np.median(a[good]) < 1.3
    # Every gross measurement is gone: removed, or its edgelet is bad because it was the source measurement.
    source_of = m.edgelets.view("source_kf")[eb.obs.edgelet]
    gross_source = eb.gross & (eb.obs.kf == source_of)
    assert eb.gross.sum() >= 20 and gross_source.any()
    assert set(np.flatnonzero(~good)) == set(eb.obs.edgelet[gross_source])
    kept = set(zip(m.edgelets.view("meas_kf").tolist(), m.edgelets.view("meas_edgelet").tolist()))
    gross_pairs = set(zip(eb.obs.kf[eb.gross].tolist(), eb.obs.edgelet[eb.gross].tolist()))
    assert not kept & gross_pairs
    assert len(kept) >= (~eb.gross).sum() - 10 * (~good).sum()  # only the bad edgelets' good ones went with them


def test_edgelets_stay_put_when_off(problem):
    _, eb = problem
    mm = _mapper(problem, enabled=False)
    mm.bundle_adjust(recent=False)
    # Not adjusted: moved only by the similarity about keyframe 0 that holds the map's scale (mapping/gauge.py),
    # one factor for every edgelet, with their directions unchanged.
    c0 = mm.map.camera_centres[0]
    rel, rel0 = mm.map.edgelets.view("centre") - c0, eb.init.centre - c0
    factor = float((rel * rel0).sum() / (rel0 * rel0).sum())
    assert np.allclose(rel, factor * rel0, rtol=0, atol=1e-12) and abs(factor - 1.0) < 0.05
    assert np.allclose(mm.map.edgelets.view("direction"), eb.init.direction, rtol=0, atol=1e-12)
    assert mm.map.edgelets.n_measurements == len(eb.obs.kf)


def test_local_adjustment_moves_only_the_local_edgelets(problem):
    """Edgelets 0-19 lose their measurements in the keyframes local BA adjusts (the newest and its 4 nearest):
    they are not adjusted; the others are (PTAM eq. 11's Z, for edgelets)."""
    prob, eb = problem
    mm = _mapper(problem, enabled=True)
    m = mm.map
    sets = local_sets(m.kf_T_cw, m.meas_kf, m.meas_pt, m.n_points_total, m.n_keyframes - 1, 4)
    kf, e = m.edgelets.view("meas_kf"), m.edgelets.view("meas_edgelet")
    m.remove_edgelet_measurements(sets.adjust[kf] & (e < 20))
    mm.bundle_adjust(recent=True)
    assert mm.stats["local_ba"]
    moved = np.any(m.edgelets.view("centre") != eb.init.centre, axis=1)
    assert not moved[:20].any() and moved[20:][~m.edgelets.view("bad")[20:]].all()


def test_removed_measurements_take_their_table_rows(problem):
    m = _mapper(problem, enabled=True).map  # a map handed to the mapper gets its visibility tables (§5.2)
    kf, e = m.edgelets.view("meas_kf"), m.edgelets.view("meas_edgelet")
    assert all(np.array_equal(np.sort(m.edgelets.tables[k][0]), np.sort(e[kf == k])) for k in (1, 2))
    n1, n2 = len(m.edgelets.tables[1][0]), len(m.edgelets.tables[2][0])
    drop = (kf == 1) & (e % 3 == 0)
    v0 = m.version
    m.remove_edgelet_measurements(drop)
    t1 = m.edgelets.tables[1]
    assert m.version > v0 and len(t1[0]) == n1 - drop.sum() and not np.any(t1[0] % 3 == 0)
    assert all(len(a) == len(t1[0]) and not a.flags.writeable for a in t1)
    assert len(m.edgelets.tables[2][0]) == n2 and m.edgelets.n_measurements == len(kf) - drop.sum()
