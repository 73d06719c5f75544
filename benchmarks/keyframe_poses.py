"""Keyframes handed over at wrong poses, over repeated runs of a scene (not part of CI).

A keyframe keeps the pose the tracker hands over with it (PTAM §6.2), and its new points are found along the
epipolar lines that pose gives: a keyframe taken at a wrong pose can grow the map around itself wrongly, and the
frames tracked against that part of the map are then reported tracked while off. In ``realtime`` the frame that
becomes a keyframe depends on when the mapper finishes with the previous one, so runs differ. This repeats a scene
and prints, per run, ATE, correct fraction and glitches, and every keyframe whose pose was off by more than the
``eval`` criteria when it was handed over: that error, the error it has in the final map, and how many of the
local bundle adjustments run with it as the newest keyframe converged (the others stopped at the iteration limit
or were aborted by a newer keyframe). Errors are against ground truth after a similarity that aligns the final
keyframe positions.

    python benchmarks/keyframe_poses.py                     # desk_corner_blur, realtime, 20 runs
    python benchmarks/keyframe_poses.py --scene desk_blur --mode async --runs 5 --set edgelets.enabled=false
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from ptam.bench.accuracy import run_accuracy
from ptam.config import load_config
from ptam.errors import PtamError
from ptam.eval.ate import ate
from ptam.eval.correctness import rotation_errors_deg
from ptam.eval.tum_io import read_tum
from ptam.geometry import se3
from ptam.mapping.map_maker import MapMaker
from ptam.synthetic import ensure_sequence
from ptam.vocabulary import RunMode


def _record_handovers(log: dict) -> None:
    """Wrap ``MapMaker.add_keyframe``: the mapper, and each request's timestamp and camera-to-world pose once a
    map exists (the initialisation's keyframes are posed in a frame the map is moved out of, PTAM §6.1)."""
    add = MapMaker.add_keyframe

    def recorded(self, request, now=False):
        log["mapper"] = self
        if self.initialised:
            log["handed"].append((request.timestamp, se3.inv(request.T_cw)))
        return add(self, request, now)

    MapMaker.add_keyframe = recorded


def _keyframe_errors(log: dict, t_gt: np.ndarray, T_gt: np.ndarray, cfg) -> tuple[list[str], bool]:
    """One line per keyframe handed over off by more than the criteria; whether a local BA run with one of them
    as the newest keyframe stopped unconverged (at the iteration limit, or aborted by a newer keyframe)."""
    m = log["mapper"].map
    ts = np.array([k.timestamp for k in m.keyframes])
    final = np.array([se3.inv(T) for T in m.kf_T_cw])
    gt = T_gt[np.abs(t_gt[None, :] - ts[:, None]).argmin(axis=1)]
    fit = ate(gt[:, :3, 3], final[:, :3, 3])
    converged: dict[int, list[bool]] = {}
    for n, _, ok in log["mapper"].stats["local_ba"]:
        converged.setdefault(n - 1, []).append(bool(ok))

    def error(T_wc: np.ndarray, k: int) -> tuple[float, float]:
        position = 1e3 * float(np.linalg.norm(fit.aligned(T_wc[None, :3, 3])[0] - gt[k, :3, 3]))
        return position, float(rotation_errors_deg(gt[k, :3, :3], T_wc[:3, :3], fit.R))

    lines, stuck = [], False
    for t, T_wc in log["handed"]:
        k = int(np.argmin(np.abs(ts - t)))
        mm, deg = error(T_wc, k)
        if mm <= cfg.eval.correct_mm and deg <= cfg.eval.correct_deg:
            continue
        fmm, fdeg = error(final[k], k)
        c = converged.get(k, [])
        stuck |= not all(c)
        lines.append(
            f"    keyframe {k} (t={t:.3f} s): handed over {mm:.0f} mm {deg:.2f}°, final {fmm:.0f} mm {fdeg:.2f}°; "
            f"local BAs converged {sum(c)}/{len(c)}"
        )
    return lines, stuck


def _positive(text: str) -> int:
    n = int(text)
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {n}")
    return n


def main() -> None:
    try:
        _run()
    except PtamError as e:  # a bad scene or --set: one line, exit status 2 (as ptam's command line)
        print(f"keyframe_poses: {e}", file=sys.stderr)
        sys.exit(2)


def _run() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="desk_corner_blur")
    ap.add_argument("--mode", default="realtime", choices=[m.value for m in RunMode])
    ap.add_argument("--runs", type=_positive, default=20)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="config override")
    args = ap.parse_args()
    cfg = load_config(None, args.set)
    t_gt, T_gt = read_tum(ensure_sequence(args.scene, cfg.synthetic) / "groundtruth.txt")
    log: dict = {}
    _record_handovers(log)
    glitches, off_runs, stuck_runs = [], 0, 0
    for i in range(args.runs):
        log.update(handed=[], mapper=None)
        s = run_accuracy(cfg, args.scene, RunMode(args.mode)).score
        glitches.append(s.glitches)
        print(
            f"run {i}: ATE {1e3 * s.ate_rmse_m:.2f} mm, {100 * s.correct_fraction:.1f} % correct, {s.glitches} glitches"
        )
        lines, stuck = _keyframe_errors(log, t_gt, T_gt, cfg) if log["mapper"] is not None else ([], False)
        off_runs += bool(lines)
        stuck_runs += stuck
        for line in lines:
            print(line)
    print(
        f"{args.scene} {args.mode}: {off_runs} of {args.runs} runs handed over a keyframe off by more than "
        f"{cfg.eval.correct_mm} mm or {cfg.eval.correct_deg}°, {stuck_runs} with a local BA after one that did not "
        f"converge; glitches median {np.median(glitches):.0f}, max {max(glitches)}"
    )


if __name__ == "__main__":
    main()
