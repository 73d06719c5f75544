"""A hand swept quickly in front of the camera (not part of CI): Agility §9.3's moving clutter.

Agility §9.3 names the weakness of its image-based motion initialisation (§6): "The motion initialisation method
is susceptible to moving clutter in the image, such as a hand moved rapidly before the camera. Such moving clutter
can cause tracking to fail, or (worse) shift tracking to a local minimum". This measures it. A bundled scene's
frames are copied and, on each pass, a motion-blurred hand (a smooth grey ellipse, blurred over its own motion
during the exposure) crosses the image from right to left in ``--frames-per-pass`` frames; the copy is tracked by
``ptam run`` as a subprocess and scored against the scene's ground truth. It prints the run's ATE, correct fraction
and glitches, and every frame tracked outside the ``eval`` criteria or not tracked, with the pass it falls in.

    python benchmarks/moving_clutter.py                          # desk_table, sync, six passes of 5 frames
    python benchmarks/moving_clutter.py --mode realtime
    python benchmarks/moving_clutter.py --set rotation.enabled=false   # PTAM's motion model alone
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

from ptam.bench.accuracy import criteria
from ptam.config import load_config
from ptam.eval.associate import associate
from ptam.eval.correctness import correctness
from ptam.eval.score import score_poses
from ptam.eval.tum_io import read_tum
from ptam.synthetic import ensure_sequence

HAND_AXES = (0.16, 0.45)  # the hand's half-width and half-height, fractions of the image's
HAND_GREY, HAND_SHADE, HAND_SHADE_PERIOD_PX = 150.0, 30.0, 40.0  # smooth shading, no corners inside the hand
EXPOSURE_STEPS = 8  # positions averaged over the exposure (half a frame interval) for the hand's motion blur


def _hand(shape: tuple[int, int], s: float, frames: int) -> np.ndarray:
    """The hand's coverage (H, W) in [0, 1] at pass position ``s`` in (0, 1): its centre sweeps from right of the
    image to left of it over ``frames`` frames."""
    h, w = shape
    travel = 1.8 * w
    cover = np.zeros((h, w), np.float32)
    for k in range(EXPOSURE_STEPS):
        x = w * 1.4 - travel * s + (k / (EXPOSURE_STEPS - 1) - 0.5) * 0.5 * travel / frames
        m = np.zeros((h, w), np.uint8)
        axes = (int(HAND_AXES[0] * w), int(HAND_AXES[1] * h))
        cv2.ellipse(m, (int(x), int(0.55 * h)), axes, 10, 0, 360, 255, -1)
        cover += m.astype(np.float32) / (255.0 * EXPOSURE_STEPS)
    return cover


def cluttered_copy(seq: Path, out: Path, passes: list[int], frames: int) -> dict[int, int]:
    """``seq`` copied to ``out`` with the hand drawn over the frames of each pass; frame index -> pass start."""
    shutil.copytree(seq, out)
    names = [ln.split()[1] for ln in (out / "rgb.txt").read_text().splitlines() if ln.strip() and ln[0] != "#"]
    in_pass = {}
    for i, name in enumerate(names):
        start = next((p for p in passes if p <= i < p + frames), None)
        if start is None:
            continue
        in_pass[i] = start
        path = out / name
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED).astype(np.float32)
        cover = _hand(image.shape[:2], (i - start + 0.5) / frames, frames)
        xx = np.arange(image.shape[1], dtype=np.float32)[None, :]
        skin = np.broadcast_to(HAND_GREY + HAND_SHADE * np.sin(xx / HAND_SHADE_PERIOD_PX), cover.shape)
        if image.ndim == 3:
            cover, skin = cover[..., None], skin[..., None]
        cv2.imwrite(str(path), np.clip(image * (1 - cover) + skin * cover, 0, 255).astype(np.uint8))
    return in_pass


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default="desk_table")
    p.add_argument("--mode", default="sync", choices=("sync", "async", "realtime"))
    p.add_argument("--passes", default="120,180,240,300,360,420", help="first frame of each pass")
    p.add_argument("--frames-per-pass", type=int, default=5)
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE")
    a = p.parse_args(argv)
    cfg = load_config(None, a.set)
    seq = ensure_sequence(a.scene, cfg.synthetic)
    with tempfile.TemporaryDirectory() as tmp:
        copy, traj = Path(tmp) / "clutter", Path(tmp) / "trajectory.txt"
        in_pass = cluttered_copy(seq, copy, [int(v) for v in a.passes.split(",")], a.frames_per_pass)
        argv_run = [sys.executable, "-m", "ptam", "run", "--dataset", str(copy), "--mode", a.mode, "--no-viewer"]
        argv_run += ["--trajectory", str(traj)] + [arg for s in a.set for arg in ("--set", s)]
        run = subprocess.run(argv_run, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if run.returncode != 0:
            print(run.stderr.strip().splitlines()[-1] if run.stderr.strip() else f"ptam run: exit {run.returncode}")
            return 2
        t_gt, T_gt = read_tum(copy / "groundtruth.txt")
        t, T = read_tum(traj)
    crit = criteria(cfg)
    s = score_poses(t_gt, T_gt, list(zip(t, T)), cfg.eval.max_time_diff_s, crit)
    print(
        f"{a.scene} {a.mode}, {len(set(in_pass.values()))} passes of {a.frames_per_pass} frames: ATE "
        f"{1e3 * s.ate_rmse_m:.2f} mm, correct {100 * s.correct_fraction:.1f} %, glitches {s.glitches}"
    )
    ig, ie = associate(t_gt, t, cfg.eval.max_time_diff_s)
    c = correctness(T_gt[ig], T[ie], len(t_gt), crit)
    off = {int(i): (1e3 * c.position_errors_m[k], c.rotation_errors_deg[k]) for k, i in enumerate(ig)}
    for i in range(len(t_gt)):
        where = f"pass at {in_pass[i]}" if i in in_pass else "no hand"
        if i not in off:
            print(f"  frame {i}: not tracked ({where})")
        elif off[i][0] > crit.max_error_m * 1e3 or off[i][1] > crit.max_error_deg:
            print(f"  frame {i}: {off[i][0]:.1f} mm, {off[i][1]:.2f} deg off ({where})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
