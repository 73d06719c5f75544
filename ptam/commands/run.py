"""``ptam run``: track a camera, a video or a dataset (or the embedded two-wall default) and build a map.

Everything asked for (trajectory, keyframes) is written at the end of the stream, on Ctrl-C and on errors
alike, then a summary is printed. A dataset that carries ``groundtruth.txt`` (TUM layout, e.g. from
``ptam synth``) is also scored: ATE after Sim(3) alignment, next to PTAM's 6 mm on its two-wall sequence.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import numpy as np

from ..camera import load_camera
from ..capture import find_calibration, open_source
from ..capture.realtime import RealtimeFeed
from ..errors import InputError
from ..eval import associate, ate, read_tum, write_tum
from ..system import System
from .run_summary import print_summary

DEFAULT_SCENE = "two_wall"
PAPER_ATE_MM = 6.0  # PTAM §7.3: standard deviation from ground truth on its synthetic two-wall sequence

log = logging.getLogger("ptam")


def _init_frames(text: str | None):
    if text is None:
        return None
    try:
        a, b = (int(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"--init-frames expects two frame numbers A,B, got '{text}'") from None
    if not 0 <= a < b:
        raise InputError(f"--init-frames needs 0 <= A < B, got {a},{b}")
    return a, b


def _open(args, cfg):
    dataset = args.dataset
    if args.camera is None and args.video is None and dataset is None:
        from ..synthetic import ensure_sequence

        print(f"ptam: no source given: replaying the embedded synthetic scene '{DEFAULT_SCENE}' "
              f"(rendered once, cached)", file=sys.stderr)
        dataset = str(ensure_sequence(DEFAULT_SCENE, cfg.synthetic.cache_dir))
    source = open_source(camera=args.camera, video=args.video, dataset=dataset, fps=args.fps, size=args.size,
                         cfg=cfg.capture)
    calibration = args.calibration or (find_calibration(dataset) if dataset else None)
    if calibration is None:
        source.close()
        raise InputError("no calibration: pass --calibration camera.yaml")
    camera = load_camera(calibration)
    if camera.size != source.size:
        source.close()
        raise InputError(f"calibration {calibration} is for {camera.width}x{camera.height} images but "
                         f"{source.name} delivers {source.size[0]}x{source.size[1]}")
    return source, camera, dataset


def _progress(frames, length):
    try:
        from tqdm import tqdm
    except ImportError:
        return frames
    return tqdm(frames, total=length, unit="frame", disable=None, leave=False, dynamic_ncols=True)


def _write_outputs(args, system: System) -> None:
    if args.trajectory:
        t = np.array([p[0] for p in system.trajectory])
        T = np.array([p[1] for p in system.trajectory]).reshape(-1, 4, 4)
        write_tum(args.trajectory, t, T, header="ptam trajectory: timestamp tx ty tz qx qy qz qw (camera-to-world)")
    if args.keyframes:
        snap = system.mapper.snapshot
        if snap is None or snap.n_keyframes == 0:
            write_tum(args.keyframes, np.zeros(0), np.zeros((0, 4, 4)), header="ptam keyframes (none)")
        else:
            t = np.array([k.timestamp for k in snap.keyframes])
            T = np.linalg.inv(snap.kf_T_cw)
            write_tum(args.keyframes, t, T, header="ptam keyframes: timestamp tx ty tz qx qy qz qw (camera-to-world)")


def _score(dataset: str | None, system: System, embedded: bool) -> None:
    gt = Path(dataset) / "groundtruth.txt" if dataset else None
    if gt is None or not gt.is_file() or len(system.trajectory) < 3:
        return
    t_gt, T_gt = read_tum(gt)
    t = np.array([p[0] for p in system.trajectory])
    T = np.array([p[1] for p in system.trajectory])
    ig, ie = associate(t_gt, t, 0.01)
    if len(ig) < 3:
        return
    r = ate(T_gt[ig, :3, 3], T[ie, :3, 3])
    length = float(np.linalg.norm(np.diff(T_gt[:, :3, 3], axis=0), axis=1).sum())
    paper = f" (PTAM §7.3 reports {PAPER_ATE_MM:g} mm on its two-wall sequence)" if embedded else ""
    print(f"ATE against {gt}: {1e3 * r.rmse:.2f} mm RMSE after Sim(3) alignment over {len(ig)}/{len(t_gt)} "
          f"poses, path {length:.2f} m{paper}")


def main(args, cfg) -> int:
    logging.basicConfig(level=logging.INFO, format="ptam: %(message)s", stream=sys.stderr)
    mode = args.mode or cfg.system.mode
    init_frames = _init_frames(getattr(args, "init_frames", None))
    embedded = args.camera is None and args.video is None and args.dataset is None
    source, camera, dataset = _open(args, cfg)
    system = System(camera, cfg, mode=mode, init_frames=init_frames)
    feed = RealtimeFeed(source) if mode == "realtime" else source
    interrupted = False
    try:
        with source, system:
            for frame in _progress(feed, source.length):
                system.process(frame)
    except KeyboardInterrupt:
        interrupted = True
        print("ptam: interrupted; writing what was computed", file=sys.stderr)
    finally:
        _write_outputs(args, system)
    dropped = feed.dropped if isinstance(feed, RealtimeFeed) else None
    print_summary(system, mode, dropped)
    if not system.mapper.initialised:
        reason = system.last_failure or "no frame gave a usable stereo pair"
        print(f"initialisation did not succeed: {reason}")
    _score(dataset, system, embedded)
    return 130 if interrupted else 0
