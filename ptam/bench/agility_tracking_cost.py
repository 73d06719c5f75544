"""``ptam bench agility``'s cost of edgelets in the tracker (Agility §9.2: "frame-to-frame processing for the
illustrated map requires 12ms per frame when tracking only point features and 18ms when tracking points and
edgelets").

Each of Fig. 5's scenes (``agility_features``) and desk_bricks (an edge-rich desk, mapped at a steady pace, as the
paper's illustrated map was) is tracked in sync mode twice, with edgelets and with points alone
(``edgelets.enabled: false``), each run building its own map; the tracker's median and 95th-percentile wall time
per frame are compared. On Fig. 5's scenes the run with edgelets is Fig. 5's own.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..system import System
from .agility_features import run_features_by_motion

PAPER_MS = (12.0, 18.0)  # points alone, points and edgelets (Agility §9.2)
EXTRA_SCENES = ("desk_bricks",)  # besides Fig. 5's


def _ms(system: System) -> tuple[float, float]:
    ms = np.asarray(system.stats.track_ms, dtype=np.float64)
    return float(np.median(ms)), float(np.percentile(ms, 95))


def tracking_cost(seq: Path, cfg, with_edgelets: System | None = None) -> dict:
    """Median and p95 tracker ms per frame of ``with_edgelets`` (a sync run of ``seq`` with ``cfg``; run here when
    not given) and of a points-alone run of the same sequence."""
    if with_edgelets is None:
        _, with_edgelets = run_features_by_motion(seq, cfg)
    _, points_alone = run_features_by_motion(seq, cfg.replace(**{"edgelets.enabled": False}))
    (em, ep), (pm, pp) = _ms(with_edgelets), _ms(points_alone)
    return {"edgelets_median": em, "edgelets_p95": ep, "points_median": pm, "points_p95": pp}


def print_tracking_cost(costs: dict[str, dict], out=print) -> None:
    out("")
    out(
        f"Tracker ms per frame, sync, points alone against points and edgelets "
        f"(Agility §9.2: {PAPER_MS[0]:.0f} -> {PAPER_MS[1]:.0f} ms, +{PAPER_MS[1] - PAPER_MS[0]:.0f})"
    )
    out(f"{'scene':<14}{'points median':>15}{'p95':>8}{'+edgelets median':>18}{'p95':>8}{'added':>8}")
    for scene, c in costs.items():
        added = c["edgelets_median"] - c["points_median"]
        out(
            f"{scene:<14}{c['points_median']:>15.1f}{c['points_p95']:>8.1f}"
            f"{c['edgelets_median']:>18.1f}{c['edgelets_p95']:>8.1f}{added:>+8.1f}"
        )
