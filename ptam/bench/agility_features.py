"""``ptam bench agility``'s Fig. 5 rows: point and edgelet measurements per frame against image motion (Agility
§9.3, Fig. 5: "as the camera is moved with increasing speed, causing motion blur, the number of point features
measured drops rapidly below the number of available edgelet measurements"; at ~54 px of motion, 18 points
against 151 edgelets).

Each scene runs in sync mode with the given config: desk_blur (fast sweeps rendered with motion blur over a desk of
gravel and photographs, whose straight edges are few) and bricks_blur (the same kind of sweeps over a brick wall,
edge-rich as the paper's office is).
A frame's image motion is the median displacement, between the previous frame's pose and its own, of the map
points it found, projected with the final map; frames are binned by it and the points and edgelets found are
averaged per bin. Then the fastest frames one by one.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..camera import load_camera
from ..capture import open_dataset
from ..geometry import se3
from ..system import System

FIG5_SCENES = ("desk_blur", "bricks_blur")
MOTION_BINS_PX = (0, 5, 10, 20, 30, 40, 50, 60, 80)
FASTEST_FRAMES = 6


def _motion_px(camera, T_prev: np.ndarray, T: np.ndarray, X: np.ndarray) -> float:
    """Median image displacement (px) of world points X (N, 3) between two poses."""
    a = camera.project(se3.transform(T_prev, X))
    b = camera.project(se3.transform(T, X))
    return float(np.median(np.linalg.norm(b - a, axis=1)))


def run_features_by_motion(seq: Path, cfg) -> tuple[list[tuple[int, float, int, int]], System]:
    """(frame, image motion px, points found, edgelets found) for each frame of a sequence directory with a pose
    in the map's frame after another, and the system that tracked it (its trajectory and timings)."""
    camera = load_camera(seq / "camera.yaml")
    found: list[tuple[int, np.ndarray, np.ndarray, int]] = []
    with open_dataset(seq, cfg.capture.default_fps) as source, System(camera, cfg, mode="sync") as system:
        for frame in source:
            o = system.process(frame)
            if o.T_cw is not None and o.result is not None:  # a pose in the map's frame
                m = o.result.measurements
                found.append((int(o.index), o.T_cw, m.point_ids[m.found], o.result.n_edgelets_found))
    X = system.mapper.snapshot.X
    rows = []
    for (i0, T0, _, _), (i, T, ids, n_edge) in zip(found, found[1:]):
        if i == i0 + 1 and len(ids):
            rows.append((i, _motion_px(camera, T0, T, X[ids]), len(ids), n_edge))
    return rows, system


def print_features_by_motion(rows: list[tuple[int, float, int, int]], scene: str, out=print) -> None:
    out("")
    out(f"Features found against image motion ({scene}, sync; Agility Fig. 5: ~54 px -> 18 points, 151 edgelets)")
    out(f"{'motion px/frame':<18}{'frames':>8}{'points':>10}{'edgelets':>10}")
    motion = np.array([r[1] for r in rows])
    for lo, hi in zip(MOTION_BINS_PX, MOTION_BINS_PX[1:] + (np.inf,)):
        sel = [r for r, m in zip(rows, motion) if lo <= m < hi]
        if sel:
            label = f"{lo}-{hi}" if np.isfinite(hi) else f"{lo}+"
            out(f"{label:<18}{len(sel):>8}{np.mean([r[2] for r in sel]):>10.1f}{np.mean([r[3] for r in sel]):>10.1f}")
    for i in np.argsort(-motion)[:FASTEST_FRAMES]:
        frame, m, points, edgelets = rows[i]
        out(f"  frame {frame}: {m:.0f} px, {points} points, {edgelets} edgelets")
