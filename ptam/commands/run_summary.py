"""The end-of-run summary of ``ptam run``: what a user checks first after a run."""

from __future__ import annotations

import numpy as np

from ..map.groups import keyframe_groups
from ..vocabulary import GroupKind


def print_summary(system, mode: str, dropped: int | None, viewer=None, checkpoints: int = 0) -> None:
    """Frames, tracked %, lost events, relocalisations, keyframes, points, edgelets; median / p95 tracking ms, bundle
    adjustment runs, the median edgelet job per keyframe, frames dropped in realtime mode, frames the viewer had no
    time to log and map checkpoints written during the run."""
    s = system.stats
    snap = system.mapper.snapshot
    kfs = snap.n_keyframes if snap is not None else 0
    panoramas = [g for g in keyframe_groups(snap) if g.kind == GroupKind.PANORAMA] if kfs else []
    pts = snap.n_points if snap is not None else 0
    edgelets = len(snap.good_edgelet_indices) if snap is not None else 0
    ms = np.asarray(s.track_ms) if s.track_ms else np.zeros(1)
    ba = system.mapper.stats
    tracked = 100.0 * s.tracked / max(s.frames, 1)
    print(
        f"frames {s.frames}  tracked {s.tracked} ({tracked:.1f}%)  lost events {s.lost_events}  "
        f"relocalisations {s.relocalisations}  keyframes {kfs}  points {pts}"
        + (f"  edgelets {edgelets}" if system.cfg.edgelets.enabled else "")
        + (
            f"  (panorama: {sum(len(g.keyframes) - 1 for g in panoramas)} keyframes in {len(panoramas)} groups, "
            f"{int(np.count_nonzero(snap.ray & ~snap.bad))} rays)"
            if panoramas
            else ""
        )
    )
    line = (
        f"tracking ms median {np.median(ms):.1f}  p95 {np.percentile(ms, 95):.1f}  "
        f"BA runs {len(ba['local_ba']) + len(ba['global_ba'])} (local {len(ba['local_ba'])}, "
        f"global {len(ba['global_ba'])})  mode {mode}"
    )
    jobs = ba.get("edgelet_jobs", [])
    if jobs:  # Agility §9.2 times edgelet extraction per keyframe; the §5.2 tables are the job's last step
        line += (
            f"  edgelet job ms median {np.median([j.ms for j in jobs]):.1f}"
            f" (tables {np.median([j.tables_ms for j in jobs]):.1f})"
        )
    old_kfs = ba.get("edgelet_old_keyframes_ms", [])
    if old_kfs:  # Agility §4.4: the new edgelets measured in the old keyframes when the mapper is idle
        line += f"  in old keyframes {np.median(old_kfs):.1f}"
    if dropped is not None:
        line += f"  dropped frames {dropped}"
    if viewer is not None and viewer.dropped:
        line += f"  frames not shown in the viewer {viewer.dropped}"
    if checkpoints:
        line += f"  checkpoints {checkpoints}"
    print(line)
    if jobs:
        print(_edgelet_funnel(jobs))
    if s.tracks_created > 1:  # Gauglitz §4.4-§5.3
        others = system.other_tracks
        print(
            f"tracks {s.tracks_created}, merged {s.tracks_merged}; the trajectory holds the largest "
            f"({len(system.trajectory)} frames)"
            + (f", {len(others)} unmerged with {sum(map(len, others.values()))} frames" if others else "")
        )


def _edgelet_funnel(jobs) -> str:
    """How many of the keyframes' edgelet candidates were left after each step of Agility §4.3, summed over the
    run's edgelet jobs (``EdgeletJob.FUNNEL``)."""
    counts = [sum(getattr(j, name) for j in jobs) for name in jobs[0].FUNNEL]
    return "edgelet candidates " + " -> ".join(
        f"{name} {n}" if i else str(n) for i, (name, n) in enumerate(zip(jobs[0].FUNNEL, counts))
    )
