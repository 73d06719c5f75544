"""``ptam bench ba``: PTAM Table 2 (bundle-adjustment timings) measured on synthetic maps shaped like PTAM's.

A map of N keyframes: the camera explores along a wall about 3 m away (keyframes 0.1 × depth apart, PTAM's
keyframe spacing heuristic §6.2), each pair of consecutive keyframes creates ``POINTS_PER_PAIR`` points (as
epipolar search does, §6.2; 150 keyframes → 6000 points, PTAM §7.2's practical limit), and every keyframe
that sees a point measures it (PTAM §6.4 re-finds new points in all keyframes). Measurement levels follow
PTAM-like fractions, noise is 1 px × 2^level, and 5% of the measurements are gross outliers.

Global BA starts from poses perturbed by 2 cm / 1° and points by 5 cm with the first keyframe fixed (a
harder start than PTAM's, whose global BA follows local ones). Local BA starts from the globally adjusted
map with the newest keyframe as the tracker would deliver it (3 mm / 0.05°) and the points of the newest
pair with a 5 cm triangulation depth error. A start far worse than the rest of the map would not work:
the Tukey cut-off comes from the median over all measurements, mostly from the well-fitting fixed keyframes,
so a keyframe off by 1° loses all its measurements as outliers in the first iteration (as in PTAM).
Timings exclude numba compilation (a warm-up problem runs first).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..camera.fov import FovCamera
from ..geometry import se3, so3
from ..mapping.bundle import Bundle
from ..mapping.local_ba import local_bundle_adjust

# PTAM Table 2 (ms, mean), keyframe buckets 2-49 / 50-99 / 100-149.
PTAM_TABLE2_MS = {"local": (170.0, 270.0, 440.0), "global": (380.0, 1700.0, 6900.0)}
BUCKETS = ((2, 49), (50, 99), (100, 149))
BENCH_KEYFRAMES = (10, 30, 50, 75, 100, 125, 150)  # two map sizes per bucket, and 150 beyond the table
POINTS_PER_PAIR = 40
LOCAL_REPEATS = 3
SEED = 2007

# The synthetic map's shape: PTAM's 640×480 camera with FOV distortion, a wall ~3 m away.
CAMERA = dict(width=640, height=480, fx=384.0, fy=384.0, cx=319.5, cy=239.5, omega=0.9)
WALL_DEPTH_M = 3.0
WALL_RELIEF_M = 0.5
KEYFRAME_SPACING_REL = 0.1  # PTAM §6.2: a new keyframe after moving ~0.1 × scene depth
ORIENTATION_JITTER_DEG = 3.0
LEVEL_FRACTIONS = (0.5, 0.3, 0.15, 0.05)
NOISE_PX = 1.0
OUTLIER_FRACTION = 0.05
OUTLIER_SIGMAS = (12.0, 40.0)  # gross: far outside Tukey's cut-off (~8σ)
POSE_PERTURBATION = (0.02, 1.0)  # m, degrees
POINT_PERTURBATION_M = 0.05
# Local BA's start: a new keyframe as accurate as the tracker makes it (~0.5 px) and new points with the
# depth error of a short-baseline triangulation (§6.2), along the ray from the new keyframe.
NEW_KEYFRAME_PERTURBATION = (0.003, 0.05)  # m, degrees
NEW_POINT_DEPTH_ERROR_M = 0.05


@dataclass(frozen=True)
class SyntheticBA:
    camera: FovCamera
    poses_true: np.ndarray  # (N, 4, 4) T_cw
    points_true: np.ndarray  # (M, 3)
    poses_init: np.ndarray  # poses_true perturbed
    points_init: np.ndarray  # points_true perturbed
    point_pair: np.ndarray  # (M,) the keyframe pair (i, i + 1) that created point j, as i
    meas_kf: np.ndarray
    meas_pt: np.ndarray
    meas_xy: np.ndarray
    meas_level: np.ndarray
    gross: np.ndarray  # (K,) bool, the gross outliers


def perturb_poses(T: np.ndarray, rng, metres: float, degrees: float) -> np.ndarray:
    """exp(μ)·T with a translation of exactly ``metres`` and a rotation of ``degrees`` in random directions."""
    v = rng.normal(size=(len(T), 3))
    w = rng.normal(size=(len(T), 3))
    mu = np.concatenate(
        [
            metres * v / np.linalg.norm(v, axis=1, keepdims=True),
            np.radians(degrees) * w / np.linalg.norm(w, axis=1, keepdims=True),
        ],
        axis=1,
    )
    return se3.exp(mu) @ T


def perturb_points(X: np.ndarray, rng, metres: float) -> np.ndarray:
    d = rng.normal(size=X.shape)
    return X + metres * d / np.linalg.norm(d, axis=1, keepdims=True)


def perturb_depths(X: np.ndarray, centre: np.ndarray, rng, metres: float) -> np.ndarray:
    """Move points along their rays from ``centre`` by N(0, ``metres``²): a triangulation's depth error."""
    ray = X - centre
    return X + metres * rng.normal(size=(len(X), 1)) * ray / np.linalg.norm(ray, axis=1, keepdims=True)


def new_keyframe_start(prob: SyntheticBA, poses: np.ndarray, points: np.ndarray, rng):
    """The map as local BA finds it after the newest keyframe arrived: its pose from the tracker and the
    points of the newest keyframe pair freshly triangulated."""
    newest = len(poses) - 1
    poses = poses.copy()
    points = points.copy()
    poses[newest] = perturb_poses(poses[newest:], rng, *NEW_KEYFRAME_PERTURBATION)[0]
    fresh = prob.point_pair == newest - 1
    centre = -poses[newest, :3, :3].T @ poses[newest, :3, 3]
    points[fresh] = perturb_depths(points[fresh], centre, rng, NEW_POINT_DEPTH_ERROR_M)
    return poses, points


def look_at(C: np.ndarray, target: np.ndarray) -> np.ndarray:
    """T_cw (N, 4, 4) of cameras at C (N, 3) with z towards ``target`` (N, 3) and y roughly down (world −y)."""
    z = target - C
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    x = np.cross([0.0, -1.0, 0.0], z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    R_cw = np.swapaxes(np.stack([x, np.cross(z, x), z], axis=2), 1, 2)
    return se3.from_Rt(R_cw, -np.einsum("nij,nj->ni", R_cw, C))


def _observe(cam, T, X, point_pair, rng, outlier_fraction, noise_px, level_fractions) -> SyntheticBA:
    """Measure every point in every keyframe that sees it, add noise and gross outliers, perturb the state."""
    Xc = np.einsum("nij,mj->nmi", T[:, :3, :3], X) + T[:, None, :3, 3]
    vis = cam.valid(Xc)
    uv_all = np.zeros(Xc.shape[:2] + (2,))
    uv_all[vis] = cam.project(Xc[vis])
    vis &= cam.in_image(uv_all)
    meas_kf, meas_pt = np.nonzero(vis)
    k = len(meas_kf)
    fractions = np.asarray(level_fractions, dtype=np.float64)
    level = rng.choice(len(fractions), size=k, p=fractions / fractions.sum())
    sigma = noise_px * np.ldexp(1.0, level)
    xy = uv_all[meas_kf, meas_pt] + sigma[:, None] * rng.normal(size=(k, 2))
    gross = rng.random(k) < outlier_fraction
    ang = rng.uniform(0.0, 2.0 * np.pi, k)
    mag = sigma * rng.uniform(*OUTLIER_SIGMAS, k)
    xy[gross] += (mag[:, None] * np.stack([np.cos(ang), np.sin(ang)], 1))[gross]
    return SyntheticBA(
        camera=cam,
        poses_true=T,
        points_true=X,
        poses_init=perturb_poses(T, rng, *POSE_PERTURBATION),
        points_init=perturb_points(X, rng, POINT_PERTURBATION_M),
        point_pair=point_pair,
        meas_kf=meas_kf,
        meas_pt=meas_pt,
        meas_xy=xy,
        meas_level=level,
        gross=gross,
    )


def synthetic_ba_problem(
    n_keyframes: int,
    n_points: int,
    seed: int,
    camera: FovCamera | None = None,
    outlier_fraction: float = OUTLIER_FRACTION,
    noise_px: float = NOISE_PX,
    level_fractions=LEVEL_FRACTIONS,
) -> SyntheticBA:
    """An exploring map: keyframes along a wall, points spread evenly over the consecutive keyframe pairs."""
    rng = np.random.default_rng(seed)
    cam = camera or FovCamera(**CAMERA)
    n = int(n_keyframes)
    i = np.arange(n)
    spacing = KEYFRAME_SPACING_REL * WALL_DEPTH_M
    C = np.stack([i * spacing, 0.05 * WALL_DEPTH_M * np.sin(0.5 * i), 0.05 * WALL_DEPTH_M * np.cos(0.3 * i)], 1)
    R_wc = so3.exp(np.radians(ORIENTATION_JITTER_DEG) * rng.normal(size=(n, 3)))
    R_cw = np.swapaxes(R_wc, 1, 2)
    T = se3.from_Rt(R_cw, -np.einsum("nij,nj->ni", R_cw, C))

    pair = np.arange(n_points) % max(n - 1, 1)
    X = np.empty((n_points, 3))
    todo = np.arange(n_points)
    w, h = cam.width - 1.0, cam.height - 1.0
    while todo.size:
        a = pair[todo]
        b = np.minimum(a + 1, n - 1)
        uv = rng.uniform([0.0, 0.0], [w, h], size=(len(todo), 2))
        ray = np.einsum("kij,kj->ki", R_wc[a], np.concatenate([cam.unproject(uv), np.ones((len(todo), 1))], 1))
        z = WALL_DEPTH_M + rng.uniform(-WALL_RELIEF_M, WALL_RELIEF_M, len(todo))
        cand = C[a] + ((z - C[a, 2]) / ray[:, 2])[:, None] * ray
        Xc = np.einsum("kij,kj->ki", T[b, :3, :3], cand) + T[b, :3, 3]
        ok = (ray[:, 2] > 0.1) & cam.valid(Xc) & cam.in_image(cam.project(Xc))
        X[todo[ok]] = cand[ok]
        todo = todo[~ok]
    return _observe(cam, T, X, pair, rng, outlier_fraction, noise_px, level_fractions)


def _global_ba(bundle: Bundle, prob: SyntheticBA):
    fixed = np.zeros(len(prob.poses_true), bool)
    fixed[0] = True  # PTAM §6.3: the first keyframe is the fixed datum
    poses = prob.poses_init.copy()
    poses[fixed] = prob.poses_true[fixed]
    t, c = time.perf_counter(), time.thread_time()
    res = bundle.adjust(poses, prob.points_init, prob.meas_kf, prob.meas_pt, prob.meas_xy, prob.meas_level, fixed)
    return res, time.perf_counter() - t, time.thread_time() - c


def _local_ba(bundle: Bundle, prob: SyntheticBA, poses, points, rng):
    newest = len(poses) - 1
    poses, points = new_keyframe_start(prob, poses, points, rng)
    fixed = np.zeros(len(poses), bool)
    fixed[0] = True
    t, c = time.perf_counter(), time.thread_time()
    res, sets = local_bundle_adjust(
        bundle, poses, points, prob.meas_kf, prob.meas_pt, prob.meas_xy, prob.meas_level, newest, fixed_keyframes=fixed
    )
    return res, sets, time.perf_counter() - t, time.thread_time() - c


def _phase_split(results) -> str:
    tot = {}
    for r in results:
        for k, v in r.phase_seconds.items():
            tot[k] = tot.get(k, 0.0) + v
    total = tot.pop("total", 0.0) or 1.0
    return " ".join(f"{k} {100.0 * v / total:.0f}%" for k, v in tot.items())


def run_ba_benchmark(cfg, out=print) -> dict:
    """Run the benchmark, print the table via ``out`` and return the bucket means (ms) and per-size rows."""
    bundle = Bundle(FovCamera(**CAMERA), cfg.bundle)
    warm = synthetic_ba_problem(6, 200, SEED)
    g, _, _ = _global_ba(bundle, warm)
    _local_ba(bundle, warm, g.poses, g.points, np.random.default_rng(SEED))

    rows = []
    out(
        f"{'KFs':>4} {'points':>6} {'meas':>7} | {'global ms':>9} {'cpu ms':>8} {'its':>3} {'conv':>4} | "
        f"{'local ms':>8} {'cpu ms':>7} {'its':>4} {'|X|':>3} {'|Y|':>3} {'|Z|':>5}"
    )
    for n_kf in BENCH_KEYFRAMES:
        rows.append(_bench_row(bundle, n_kf, out))
    busy = sum(r["global_cpu_ms"] + r["local_cpu_ms"] for r in rows) / sum(r["global_ms"] + r["local_ms"] for r in rows)
    if busy < 0.9:
        out(f"note: the solver thread got only {100 * busy:.0f}% of a core (other processes); wall times are inflated")
    means = _table2(rows, out)
    out("")
    out("where the time goes (share of total):")
    for r in rows:
        out(f"  {r['keyframes']:>3} KFs  global: {r['global_phases']}")
        out(f"  {'':>3}      local:  {r['local_phases']}")
    result = {
        "local_ba_ms_2_49": means["local"][0],
        "global_ba_ms_2_49": means["global"][0],
        "global_ba_ms_50_99": means["global"][1],
        "global_ba_ms_100_149": means["global"][2],
    }
    from .ba_edgelets import run_edgelet_rows  # the edgelet rows build on this module's maps

    edgelet_rows = run_edgelet_rows(cfg, bundle, out)
    out(" ".join(f"{k}={v:.1f}" for k, v in result.items()))
    out_rows = {"rows": rows, "edgelet_rows": edgelet_rows}
    return {**result, "local_ba_ms_50_99": means["local"][1], "local_ba_ms_100_149": means["local"][2], **out_rows}


def _bench_row(bundle: Bundle, n_kf: int, out) -> dict:
    """One map size: a global BA from perturbed poses and points, then ``LOCAL_REPEATS`` local BAs."""
    prob = synthetic_ba_problem(n_kf, POINTS_PER_PAIR * (n_kf - 1), SEED + n_kf)
    g, t_g, c_g = _global_ba(bundle, prob)
    rng = np.random.default_rng(SEED)
    locs = [_local_ba(bundle, prob, g.poses, g.points, rng) for _ in range(LOCAL_REPEATS)]
    s = locs[0][1]
    row = dict(
        keyframes=n_kf,
        points=len(prob.points_true),
        measurements=len(prob.meas_kf),
        global_ms=1e3 * t_g,
        global_cpu_ms=1e3 * c_g,
        global_iterations=g.iterations,
        global_converged=g.converged,
        local_ms=1e3 * float(np.mean([x[2] for x in locs])),
        local_cpu_ms=1e3 * float(np.mean([x[3] for x in locs])),
        local_iterations=float(np.mean([x[0].iterations for x in locs])),
        global_phases=_phase_split([g]),
        local_phases=_phase_split([x[0] for x in locs]),
    )
    out(
        f"{n_kf:>4} {row['points']:>6} {row['measurements']:>7} | {row['global_ms']:>9.1f} "
        f"{row['global_cpu_ms']:>8.1f} {g.iterations:>3} {'yes' if g.converged else 'no':>4} | "
        f"{row['local_ms']:>8.1f} {row['local_cpu_ms']:>7.1f} {row['local_iterations']:>4.1f} "
        f"{int(s.adjust.sum()):>3} {int(s.fixed.sum()):>3} {int(s.points.sum()):>5}"
    )
    return row


def _table2(rows: list[dict], out) -> dict:
    """PTAM Table 2's buckets: mean local and global BA times measured here beside the paper's."""

    def bucket_mean(key, lo, hi):
        v = [r[key] for r in rows if lo <= r["keyframes"] <= hi]
        return float(np.mean(v)) if v else float("nan")

    means = {kind: [bucket_mean(f"{kind}_ms", lo, hi) for lo, hi in BUCKETS] for kind in ("local", "global")}
    out("")
    out("PTAM Table 2, bundle adjustment mean times (ms): measured here / paper")
    out(f"{'keyframes':<10}" + "".join(f"{f'{lo}-{hi}':>20}" for lo, hi in BUCKETS))
    for kind in ("local", "global"):
        out(
            f"{kind + ' BA':<10}"
            + "".join(f"{f'{m:.0f} / {p:.0f}':>20}" for m, p in zip(means[kind], PTAM_TABLE2_MS[kind]))
        )
    return means
