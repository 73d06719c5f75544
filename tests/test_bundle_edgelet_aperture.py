"""Edgelets left in §4.3's aperture problem inside a bundle adjustment (Agility §4.3-§4.4), and the Tukey cut-off
taken from the points (``bundle.tukey_from_points``), against synthetic truth."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ptam.bench.ba_edgelets import DRAW_STRIDE, POINTS_PER_EDGELET, POINTS_PER_PAIR
from ptam.bench.ba_timing import OUTLIER_FRACTION, SEED, synthetic_ba_problem
from ptam.config import default_config
from ptam.mapping import bundle_edgelet_kernels as EK
from ptam.mapping.bundle import Bundle
from ptam.mapping.bundle_inputs import EdgeletBundleInput
from tests.reference import bundle_edgelets as RE
from tests.support.ba_problems import edgelet_errors, synthetic_edgelets, synthetic_workspace_problem

CFG = default_config()


def test_plane_angles_and_hold_kernels_match_reference():
    """The planes' angles (``ba_edgelet_plane_angles``) span what every pair compared in numpy spans, and the hold
    (``ba_edgelet_hold``) keeps and restores the same edgelets as the numpy reference, over a random subset of
    the measurements (some edgelets left with one or none) and thresholds of 5° and 20°."""
    prob = synthetic_workspace_problem(10, 300, seed=11)
    eb = synthetic_edgelets(prob, 100, seed=12)
    mkf, medg = eb.obs.kf, eb.obs.edgelet
    rng = np.random.default_rng(13)
    use = rng.random(len(mkf)) < 0.4
    frames, start = eb.truth.frames(), eb.init.frames()
    angle = np.empty(len(mkf))
    EK.ba_edgelet_plane_angles(prob.poses_true, frames, mkf, medg, angle)
    assert np.all(np.abs(angle) <= np.pi / 2) and np.all(angle[np.unique(medg, return_index=True)[1]] == 0.0)
    ref = RE.ba_edgelet_plane_spread_ref(prob.poses_true, frames, mkf, medg, use, len(frames))
    spans = []
    for read in (angle, np.where(angle < 0, angle + np.pi, angle)):  # (−π/2, π/2] and [0, π)
        lo, hi = np.full(len(frames), np.inf), np.full(len(frames), -np.inf)
        np.minimum.at(lo, medg[use], read[use])
        np.maximum.at(hi, medg[use], read[use])
        spans.append(hi - lo)
    span = np.minimum(*spans)
    two = np.bincount(medg[use], minlength=len(frames)) >= 2
    narrow = two & (ref < np.pi / 4)
    assert narrow.sum() > 30 and np.allclose(span[narrow], ref[narrow], atol=1e-12)
    assert np.all(span[two & ~narrow] >= np.pi / 4) and np.any(np.maximum(*spans)[narrow] > np.pi / 2)  # a wrap
    for deg in (5.0, 20.0):
        u, f = use.copy(), frames.copy()
        n = EK.ba_edgelet_hold(medg, u, angle, np.radians(deg), f, start)
        u_ref, f_ref = RE.ba_edgelet_hold_ref(prob.poses_true, frames, mkf, medg, use, np.radians(deg), start)
        held = np.flatnonzero(np.any(f != frames, axis=(1, 2)))
        assert np.array_equal(u, u_ref) and n == u_ref.sum() and np.array_equal(f, f_ref) and len(held) >= 5
        print(f"{deg}°: {len(held)} of {len(frames)} edgelets held")


@pytest.fixture(scope="module")
def map_with_a_lost_source():
    """The benchmark's tenth map of 75 keyframes (``ptam bench ba``): edgelet 91 is measured in keyframes 64 and
    66-74; 64's measurement is a gross outlier, and the planes of the other nine meet at 4.6° at most, under the
    5° at which §4.3 triangulates."""
    n_kf, draw = 75, 10
    prob = synthetic_ba_problem(n_kf, POINTS_PER_PAIR * (n_kf - 1), SEED + n_kf + DRAW_STRIDE * draw)
    eb = synthetic_edgelets(
        prob, len(prob.points_true) // POINTS_PER_EDGELET, SEED + DRAW_STRIDE * draw, gross_fraction=OUTLIER_FRACTION
    )
    return prob, eb


def _global(problem, edgelets=True, **bundle):
    prob, eb = problem
    fixed = np.zeros(len(prob.poses_true), bool)
    fixed[0] = True
    poses = prob.poses_init.copy()
    poses[0] = prob.poses_true[0]
    meas = (prob.meas_kf, prob.meas_pt, prob.meas_xy, prob.meas_level)
    ein = EdgeletBundleInput(eb.init, eb.obs, CFG.edgelets) if edgelets else None
    b = Bundle(prob.camera, dataclasses.replace(CFG.bundle, **bundle))
    return b.adjust(poses, prob.points_init, *meas, fixed, edgelets=ein)


def test_an_edgelet_left_in_the_aperture_problem_is_held(map_with_a_lost_source):
    """Once its source measurement is an outlier, edgelet 91 can turn freely within its planes, and eq. 6's sample
    points, placed again at every step, let LM turn it on: with the points' cut-off and no such hold it swung
    2-12° at every accepted step up to the iteration limit (measured). Held, the adjustment converges in as many
    iterations as points alone take, the edgelet back where the adjustment found it (its first step, taken while
    the source measurement was still in, had turned it 49°), and the other edgelets end near the truth."""
    prob, eb = map_with_a_lost_source
    m = np.flatnonzero(eb.obs.edgelet == 91)
    assert eb.gross[m].tolist() == [True] + [False] * 9
    alone = _global(map_with_a_lost_source, edgelets=False)
    held = _global(map_with_a_lost_source)
    free = _global(map_with_a_lost_source, hold_underdetermined=False)
    print(f"LM iterations: points alone {alone.iterations}, held {held.iterations}, free {free.iterations}")
    assert free.hit_max_iterations and not free.converged
    assert held.converged and held.iterations <= alone.iterations
    d, a = edgelet_errors(held.edgelets, eb.truth)
    d0, a0 = edgelet_errors(eb.init, eb.truth)
    assert d[91] == pytest.approx(d0[91]) and a[91] == pytest.approx(a0[91])  # back where it started
    assert np.degrees(np.arccos(abs(free.edgelets.direction[91] @ eb.truth.direction[91]))) > 30.0
    others = np.ones(len(d), bool)
    others[91] = False
    # Measured: median 5.9 mm / 0.70° from a start 30 mm / 3° off (free: 6.0 mm, 0.70°).
    assert np.median(d0) > 25.0 and np.median(d[others]) < 7.0 and np.median(a[others]) < 0.85


def test_the_edgelets_leave_the_points_cut_off_where_points_alone_put_it(map_with_a_lost_source):
    """The Tukey cut-off comes from the points' squared errors (``bundle.tukey_from_points``): with edgelets it ends
    where points alone put it (measured 7.72 against 7.72), where pooled the edgelets' tight line fits pulled it to
    6.96. Summed over ``ptam bench ba``'s maps pooling took 132 LM iterations against 118 for points alone (maps of
    30 keyframes), the points' cut-off 120."""
    alone = _global(map_with_a_lost_source, edgelets=False)
    ours = _global(map_with_a_lost_source)
    pooled = _global(map_with_a_lost_source, tukey_from_points=False)
    print(
        f"Tukey cut-off: points alone {alone.tukey_cutoff:.3f}, ours {ours.tukey_cutoff:.3f}, "
        f"pooled {pooled.tukey_cutoff:.3f}"
    )
    assert ours.tukey_cutoff == pytest.approx(alone.tukey_cutoff, rel=0.005)
    assert pooled.tukey_cutoff < 0.92 * alone.tukey_cutoff
    assert ours.iterations <= alone.iterations and ours.n_inliers == alone.n_inliers
