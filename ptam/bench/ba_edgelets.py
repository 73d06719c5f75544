"""Edgelets on the benchmark's synthetic maps (Agility §4.4, §9.2), and ``ptam bench ba``'s edgelet rows.

``synthetic_edgelets`` puts edgelets where the map has structure (at a random subset of its points, so the
keyframes that see those points see them), each with a random 3-D direction, and measures each in every keyframe
that sees it as the true image line moved along its normal and turned, with a share of gross outliers moved
far off; the start is the truth moved in random 4-DOF directions.

``run_edgelet_rows``: Agility §9.2 reports that edgelets add "a 25% extra processing burden" to bundle
adjustment, for maps with five points per edgelet (§9.1). The same global and local adjustments as Table 2's
rows run on the same map without and with ``POINTS_PER_EDGELET``-sparse edgelets, on ``EDGELET_BENCH_MAPS`` maps
of each size (other random draws), their times and LM iterations summed: on one map the two problems often
converge one iteration apart either way, which moved the whole adjustment's ratio by ±20 %. Each adjustment runs
``EDGELET_BENCH_REPEATS`` times, with and without edgelets in turn, and its fastest run counts: timed once, the
ratios of three runs of the bench on one machine spread over 0.08 (global, 30 keyframes: 1.21-1.33). Summed, the
adjustments with edgelets take about as many LM iterations as points alone (global 120 / 118 and 151 / 162 at 30 /
75 keyframes, local 91 / 89 and 91 / 90); before the Tukey cut-off came from the points (``bundle.tukey_from_points``)
they took 132 and 138, local 97 and 98. Without and with edgelets
run in alternating order from one map to the next: always points first, the local rows read +25-29 % where
alternating reads +32-37 % (the run second found the map's arrays in the caches).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..edgelet import EdgeletObservations, Edgelets, perp, project_edgelets
from ..mapping.bundle import Bundle
from ..mapping.bundle_inputs import EdgeletBundleInput
from ..mapping.local_ba import local_sets
from .ba_timing import OUTLIER_FRACTION, SEED, SyntheticBA, new_keyframe_start, synthetic_ba_problem

EDGELET_BENCH_KEYFRAMES = (30, 75)
EDGELET_BENCH_MAPS = 20  # maps per size, their times summed
EDGELET_BENCH_REPEATS = 3  # runs of each adjustment, interleaved, the fastest kept (single runs spread ±10 %)
DRAW_STRIDE = 1000  # seed offset between the maps of one size (sizes differ by less)
WARM_KEYFRAMES = 6  # a small map first, so that the edgelet kernels' numba cache loads are not timed
POINTS_PER_EDGELET = 5  # Agility §9.1: "Points outnumber edgelets by a factor of 5 to 1"
POINTS_PER_PAIR = 40
LINE_OFFSET_PX = 0.5  # measured line: N(0, 0.5²) px along its normal ...
LINE_ANGLE_DEG = 2.0  # ... and turned by N(0, 2²) degrees (an 18 px fit, Agility §4.2)
LINE_ANCHOR_PX = 3.0  # the line's anchor point anywhere within this of the projected centre
GROSS_PX = 25.0  # a gross outlier: the line moved this far along its normal (§4.2 searches 5 px)
START_PERTURBATION = (0.03, 3.0)  # m, degrees
MIN_PLANE_ANGLE_DEG = 5.0  # the default of edgelets.triangulate_min_plane_angle_deg (§4.3's aperture problem)
CANDIDATES_PER_EDGELET = 8  # random edgelets drawn per one kept (the rest fail the aperture check)


@dataclass(frozen=True)
class EdgeletBA:
    """Edgelets for a ``SyntheticBA`` problem: the truth, a perturbed start and keyframe line measurements
    (``gross``: the measurements moved far off the edge)."""

    truth: Edgelets
    init: Edgelets
    obs: EdgeletObservations
    gross: np.ndarray


def _measure(prob: SyntheticBA, truth: Edgelets, rng, offset_px: float, angle_deg: float):
    """(keyframe, edgelet, a, b) of every edgelet seen by a keyframe, with the line noise."""
    kf, ed, a, b = [], [], [], []
    for k, T in enumerate(prob.poses_true):  # one vectorised projection per keyframe
        p = project_edgelets(prob.camera, T, truth)
        seen = np.flatnonzero(p.valid & prob.camera.in_image(p.centre))
        ang = np.radians(angle_deg) * rng.normal(size=len(seen))
        u = p.unit_direction[seen]
        b.append(np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * perp(u))
        off = offset_px * rng.normal(size=(len(seen), 1))
        a.append(
            p.centre[seen] + off * p.normal[seen] + rng.uniform(-LINE_ANCHOR_PX, LINE_ANCHOR_PX, (len(seen), 1)) * u
        )
        kf.append(np.full(len(seen), k))
        ed.append(seen)
    return np.concatenate(kf), np.concatenate(ed), np.concatenate(a), np.concatenate(b)


def _triangulable(prob: SyntheticBA, truth: Edgelets, kf: np.ndarray, ed: np.ndarray, min_deg: float) -> np.ndarray:
    """Edgelets the mapper could have made (§4.3): the planes through the edgelet and the centres of the first two
    keyframes that see it (a source and its nearest target) meet at ``min_deg`` or more (else the aperture
    problem). ``kf``, ``ed``: the measurements, in keyframe order."""
    R, t = prob.poses_true[:, :3, :3], prob.poses_true[:, :3, 3]
    C = -np.einsum("nji,nj->ni", R, t)
    n = np.cross(truth.centre[ed] - C[kf], truth.direction[ed])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    idx = np.arange(len(kf))
    first = np.full(len(truth), len(kf))
    np.minimum.at(first, ed, idx)
    second = np.full(len(truth), len(kf))
    later = idx != first[ed]
    np.minimum.at(second, ed[later], idx[later])
    ok = second < len(kf)
    sin = np.zeros(len(truth))
    sin[ok] = np.linalg.norm(np.cross(n[first[ok]], n[second[ok]]), axis=1)
    return ok & (sin >= np.sin(np.radians(min_deg)))


def synthetic_edgelets(
    prob: SyntheticBA,
    n_edgelets: int,
    seed: int,
    offset_px: float = LINE_OFFSET_PX,
    angle_deg: float = LINE_ANGLE_DEG,
    perturbation: tuple[float, float] = START_PERTURBATION,
    gross_fraction: float = 0.0,
    min_plane_angle_deg: float = MIN_PLANE_ANGLE_DEG,
) -> EdgeletBA:
    """Up to ``n_edgelets`` edgelets at points of ``prob`` with random directions, among those that could be
    triangulated (``_triangulable``), measured in every keyframe that sees them; the start is the truth moved by
    ``perturbation`` (m, degrees) in random 4-DOF directions."""
    rng = np.random.default_rng(seed)
    n = min(CANDIDATES_PER_EDGELET * n_edgelets, len(prob.points_true))
    centre = prob.points_true[rng.choice(len(prob.points_true), n, replace=False)]
    truth = Edgelets(centre, rng.normal(size=(n, 3)), rng.normal(size=(n, 3))).orthonormalised()
    kf, ed, _, _ = _measure(prob, truth, rng, 0.0, 0.0)
    truth = truth.subset(np.flatnonzero(_triangulable(prob, truth, kf, ed, min_plane_angle_deg))[:n_edgelets])
    kf, ed, a, b = _measure(prob, truth, rng, offset_px, angle_deg)
    gross = rng.random(len(a)) < gross_fraction
    a[gross] += GROSS_PX * perp(b[gross])
    t, deg = perturbation
    v, w = rng.normal(size=(len(truth), 2)), rng.normal(size=(len(truth), 2))
    mu = np.concatenate(
        [
            t * v / np.linalg.norm(v, axis=1, keepdims=True),
            np.radians(deg) * w / np.linalg.norm(w, axis=1, keepdims=True),
        ],
        axis=1,
    )
    return EdgeletBA(truth, truth.updated(mu), EdgeletObservations(kf, ed, a, b), gross)


def edgelet_errors(est: Edgelets, truth: Edgelets) -> tuple[np.ndarray, np.ndarray]:
    """Each edgelet's distance from its true 3-D line (mm; the position along it is no parameter, §4.4 eq. 9)
    and the angle between the directions (degrees)."""
    off = est.centre - truth.centre
    off -= np.sum(off * truth.direction, axis=1, keepdims=True) * truth.direction
    cos = np.clip(np.abs(np.sum(est.direction * truth.direction, axis=1)), 0.0, 1.0)
    return 1e3 * np.linalg.norm(off, axis=1), np.degrees(np.arccos(cos))


def _timed(bundle: Bundle, args: tuple, **kw) -> tuple[float, int]:
    """CPU ms of the solver's thread (less sensitive than wall time to other processes) and LM iterations."""
    c = time.thread_time()
    res = bundle.adjust(*args, **kw)
    return 1e3 * (time.thread_time() - c), res.iterations


def _edgelet_row(bundle: Bundle, cfg, n_kf: int, draw: int = 0) -> dict:
    """Global BA from the perturbed start and one local BA around the newest keyframe, without and with
    edgelets, on one map (``draw`` picks another map of the same size)."""
    prob = synthetic_ba_problem(n_kf, POINTS_PER_PAIR * (n_kf - 1), SEED + n_kf + DRAW_STRIDE * draw)
    eb = synthetic_edgelets(
        prob,
        len(prob.points_true) // POINTS_PER_EDGELET,
        SEED + DRAW_STRIDE * draw,
        gross_fraction=OUTLIER_FRACTION,
        min_plane_angle_deg=cfg.edgelets.triangulate_min_plane_angle_deg,
    )
    meas = (prob.meas_kf, prob.meas_pt, prob.meas_xy, prob.meas_level)
    fixed = np.zeros(n_kf, bool)
    fixed[0] = True
    poses = prob.poses_init.copy()
    poses[0] = prob.poses_true[0]
    g = (poses, prob.points_init, *meas, fixed)
    edg = EdgeletBundleInput(eb.init, eb.obs, cfg.edgelets)
    lp, lx = new_keyframe_start(
        prob, prob.poses_true, prob.points_true, np.random.default_rng(SEED + DRAW_STRIDE * draw)
    )
    sets = local_sets(lp, prob.meas_kf, prob.meas_pt, len(lx), n_kf - 1, cfg.bundle.local_neighbours, fixed)
    near = np.zeros(len(eb.truth), bool)
    near[eb.obs.edgelet[sets.adjust[eb.obs.kf]]] = True
    loc = (lp, lx, *meas, ~sets.adjust, sets.points)
    ledg = EdgeletBundleInput(eb.truth, eb.obs, cfg.edgelets, near)
    row = dict(
        keyframes=n_kf, points=len(prob.points_true), edgelets=len(eb.truth), edgelet_measurements=len(eb.obs.kf)
    )
    for kind, args, e in (("global", g, edg), ("local", loc, ledg)):
        pair = ((kind, {}), (f"{kind}_edgelets", {"edgelets": e}))
        for r in range(EDGELET_BENCH_REPEATS):
            for name, kw in pair if (draw + r) % 2 == 0 else pair[::-1]:  # the second run finds the arrays warm
                ms, its = _timed(bundle, args, **kw)
                if ms < row.get(f"{name}_cpu_ms", np.inf):
                    row[f"{name}_cpu_ms"], row[f"{name}_iterations"] = ms, its
    return row


def _summed_row(bundle: Bundle, cfg, n_kf: int) -> dict:
    """``_edgelet_row`` on ``EDGELET_BENCH_MAPS`` maps of ``n_kf`` keyframes: the first map's sizes, the maps' CPU
    ms and LM iterations summed."""
    maps = [_edgelet_row(bundle, cfg, n_kf, draw) for draw in range(EDGELET_BENCH_MAPS)]
    row = dict(maps[0], maps=len(maps))
    for key in row:
        if key.endswith(("_cpu_ms", "_iterations")):
            row[key] = sum(m[key] for m in maps)
    return row


def run_edgelet_rows(cfg, bundle: Bundle, out=print) -> list[dict]:
    """Print and return BA times without and with edgelets on the same maps (Agility §9.2: +25 %): the whole
    adjustment and, since a different problem may converge in one LM iteration more or less, per iteration."""
    _edgelet_row(bundle, cfg, WARM_KEYFRAMES)
    out("")
    out(
        f"edgelets (Agility §9.2: edgelets add 25% to BA; here 1 edgelet per {POINTS_PER_EDGELET} points; "
        f"times and iterations summed over {EDGELET_BENCH_MAPS} maps of each size):"
    )
    out(
        f"{'KFs':>4} {'points':>6} {'edgelets':>8} | {'global cpu ms (its)':>20} {'+edgelets':>14} {'ratio':>5} "
        f"{'/it':>5} | {'local cpu ms (its)':>19} {'+edgelets':>13} {'ratio':>5} {'/it':>5}"
    )
    rows = []
    for n_kf in EDGELET_BENCH_KEYFRAMES:
        r = _summed_row(bundle, cfg, n_kf)

        def cell(name: str, width: int, r=r) -> str:
            return f"{r[f'{name}_cpu_ms']:.1f} ({r[f'{name}_iterations']})".rjust(width)

        def ratios(kind: str, r=r) -> str:
            with_e, without = r[f"{kind}_edgelets_cpu_ms"], r[f"{kind}_cpu_ms"]
            its = r[f"{kind}_iterations"] / max(r[f"{kind}_edgelets_iterations"], 1)
            return f"{with_e / without:>5.2f} {with_e / without * its:>5.2f}"

        out(
            f"{n_kf:>4} {r['points']:>6} {r['edgelets']:>8} | {cell('global', 20)} {cell('global_edgelets', 14)} "
            f"{ratios('global')} | {cell('local', 19)} {cell('local_edgelets', 13)} {ratios('local')}"
        )
        rows.append(r)
    return rows
