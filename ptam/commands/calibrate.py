"""``ptam calibrate``: detect a chessboard in a video, live camera or image folder, fit a camera model, write
camera.yaml and report the reprojection error per view."""

from __future__ import annotations

import os
import sys

import numpy as np
from tqdm import tqdm

from ..camera import save_camera
from ..camera.calibrator import CalibrationResult, calibrate
from ..camera.chessboard import ViewCollector, missing_cells, parse_board, select_views
from ..capture import open_source
from ..errors import InputError


def _open(args, cfg):
    if args.camera is None and args.video is None and args.images is None:
        raise InputError("ptam calibrate: give --video FILE, --camera v4l2[:DEVICE] | dc1394[:N|GUID] or --images DIR")
    return open_source(cfg.capture, camera=args.camera, video=args.video, dataset=args.images)


def _collect(source, collector: ViewCollector, step: int) -> int:
    """Feed frames to the collector until the source ends, the collector is full, or Ctrl-C (live cameras);
    returns the number of frames read."""
    live = source.length is None
    if live:
        print(
            f"show the {collector.board.cols}x{collector.board.rows} board to the camera in many positions and "
            "tilts, image corners included; Ctrl-C to finish",
            file=sys.stderr,
        )
    frames = 0
    bar = tqdm(total=source.length, unit="frame", desc="detecting", disable=None, leave=False)
    try:
        for frame in source:
            frames += 1
            bar.update(1)
            if frame.index % step == 0:
                collector.add(frame.index, frame.timestamp, frame.image)
                bar.set_postfix(views=len(collector.views))
            if collector.full or (live and len(collector.views) >= collector.cfg.max_views):
                break
    except KeyboardInterrupt:
        if not live:
            raise
    finally:
        bar.close()
    return frames


def _report(result: CalibrationResult, views, frames: int, detections: int, candidates: int, name: str) -> None:
    dropped = len(views) - result.n_used
    print(
        f"{len(views)} views used of {candidates} distinct chessboard views ({detections} detections in "
        f"{frames} frames of {name})"
    )
    print("  view  frame   RMS px  tilt deg")
    for i, v in enumerate(views):
        note = "" if result.used[i] else "  dropped (outlier)"
        print(f"  {i:4d} {v.frame:6d} {result.view_rms[i]:8.3f} {result.tilts_deg[i]:9.1f}{note}")
    extra = f" ({dropped} dropped as outliers)" if dropped else ""
    print(f"RMS reprojection error: {result.rms:.3f} px over {result.n_used} views{extra}")
    cam = result.camera
    params = ", ".join(f"{k}={v:.6g}" for k, v in cam.to_dict().items() if k not in ("model", "width", "height"))
    print(f"camera ({cam.model}, {cam.width}x{cam.height}): {params}")
    if cam.model == "fov":
        vec = " ".join(f"{v:.6f}" for v in cam.ptam_vector())
        print(f"PTAM's normalised 5-vector (camera.cfg: Camera.Parameters=[ {vec} ])")


def main(args, cfg) -> int:
    ccfg = cfg.calibrate
    board = parse_board(args.board, args.square)
    with _open(args, cfg) as source:
        collector = ViewCollector(board, source.size, ccfg)
        frames = _collect(source, collector, ccfg.frame_step)
        name, size = source.name, source.size
    if not collector.views:
        raise InputError(
            f"no {board.cols}x{board.rows} chessboard found in {frames} frames of {name} "
            "(check --board: it counts inner corners)"
        )
    views = select_views(collector.views, board, size, ccfg)
    observed = np.stack([v.corners for v in views])
    result = calibrate(args.model, size, board.points(), observed, ccfg)
    _report(result, views, frames, collector.detections, len(collector.views), name)
    used = observed[result.used]
    missing = missing_cells(used, size, ccfg.coverage_grid)
    if missing:
        print(
            f"ptam: warning: no detected corner in the image's {', '.join(missing)} "
            f"({ccfg.coverage_grid}x{ccfg.coverage_grid} grid): distortion there is extrapolated; "
            "add views with the board near those parts of the image",
            file=sys.stderr,
        )
    if result.tilts_deg[result.used].max() < ccfg.min_tilt_deg:
        print(
            f"ptam: warning: no view tilts the board more than {ccfg.min_tilt_deg:g} deg: focal length is poorly "
            "determined; add tilted views",
            file=sys.stderr,
        )
    out_dir = os.path.dirname(os.path.abspath(args.output))
    if not os.path.isdir(out_dir):
        raise InputError(f"cannot write {args.output}: directory {out_dir} does not exist")
    try:
        save_camera(result.camera, args.output)
    except OSError as e:
        raise InputError(f"cannot write {args.output}: {e.strerror}") from None
    print(f"wrote {args.output}")
    return 0
