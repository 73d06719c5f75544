"""``ptam bench mapping``: the whole system on two_wall (PTAM §7.2–§7.3).

Runs the sequence in ``sync`` mode (deterministic; every bundle adjustment runs to completion, so its time is
a full run as in PTAM Table 2) and again in ``async`` mode (the mapper in its own thread, as in live use).
Prints Table 2 — mean local and global BA ms by map size (2–49 / 50–99 / 100–149 keyframes) — next to the
paper's figures, the ATE after Sim(3) alignment next to the paper's 6 mm, the tracker's median ms per frame in
both modes (waiting excluded: the tracker's own time), and one machine-readable line.
"""

from __future__ import annotations

import numpy as np

from ..eval.score import score_trajectory
from ..synthetic import ensure_sequence
from ..vocabulary import RunMode

PTAM_TABLE2_MS = {"local": (170.0, 270.0, 440.0), "global": (380.0, 1700.0, 6900.0)}
BUCKETS = ((2, 49), (50, 99), (100, 149))
PAPER_ATE_MM = 6.0


def _run(cfg, seq, mode):
    from ..system import run_dataset  # eval observes the system; imported late to keep `ptam eval` light

    system = run_dataset(seq, cfg, mode)
    score = score_trajectory(seq / "groundtruth.txt", system.trajectory)
    return system, 1e3 * score.ate_rmse_m, score.tracked_fraction


def _bucket_means(runs):
    out = []
    for lo, hi in BUCKETS:
        ms = [m for n, m, _ in runs if lo <= n <= hi]
        out.append((float(np.mean(ms)) if ms else float("nan"), len(ms)))
    return out


def run_mapping_benchmark(cfg, scene: str = "two_wall", out=print) -> dict:
    seq = ensure_sequence(scene, cfg.synthetic)
    out(f"running {scene} in sync mode ...")
    sync, ate_mm, fraction = _run(cfg, seq, RunMode.SYNC)
    out(f"running {scene} in async mode ...")
    asyn, ate_async, fraction_async = _run(cfg, seq, RunMode.ASYNC)
    snap = sync.mapper.snapshot
    st = sync.mapper.stats
    out("")
    out(f"PTAM Table 2 on {scene} (sync run; mean ms, runs in brackets)")
    out(f"{'keyframes':<28}" + "".join(f"{f'{lo}-{hi}':>22}" for lo, hi in BUCKETS))
    for kind in ("local", "global"):
        means = _bucket_means(st[f"{kind}_ba"])
        cells = "".join(
            f"{f'{m:.0f} ({k}) / {p:.0f}':>22}" if k else f"{f'- / {p:.0f}':>22}"
            for (m, k), p in zip(means, PTAM_TABLE2_MS[kind])
        )
        out(f"{kind + ' BA, here / PTAM':<28}{cells}")
    t_sync = sync.stats.track_ms.median()
    t_async = asyn.stats.track_ms.median()
    out("")
    out(
        f"ATE after Sim(3): sync {ate_mm:.2f} mm ({100 * fraction:.1f}% tracked), async {ate_async:.2f} mm "
        f"({100 * fraction_async:.1f}% tracked); PTAM §7.3: {PAPER_ATE_MM:g} mm"
    )
    out(
        f"tracker median ms per frame: sync {t_sync:.2f}, async {t_async:.2f} "
        f"({100 * (t_async / t_sync - 1):+.0f}% with the mapper running beside it)"
    )
    local = [m for _, m, _ in st["local_ba"]]
    glob = [m for _, m, _ in st["global_ba"]]
    res = {
        "ate_mm": ate_mm,
        "tracked_fraction": fraction,
        "keyframes": snap.n_keyframes,
        "points": snap.n_points,
        "local_ba_ms_mean": float(np.mean(local)) if local else float("nan"),
        "global_ba_ms_mean": float(np.mean(glob)) if glob else float("nan"),
        "track_ms_median": t_sync,
        "track_ms_median_async": t_async,
        "ate_mm_async": ate_async,
        "tracked_fraction_async": fraction_async,
    }
    out(
        f"ate_mm={res['ate_mm']:.3f} tracked_fraction={res['tracked_fraction']:.4f} keyframes={res['keyframes']} "
        f"points={res['points']} local_ba_ms_mean={res['local_ba_ms_mean']:.1f} "
        f"global_ba_ms_mean={res['global_ba_ms_mean']:.1f} track_ms_median={res['track_ms_median']:.2f}"
    )
    return res
