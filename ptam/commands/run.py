"""``ptam run``: open the frame source and calibration and check they agree. Tracking itself (the System of
DESIGN.md) is wired in here once it exists."""

from __future__ import annotations

from ..camera import load_camera
from ..capture import find_calibration, open_source
from ..errors import InputError, PtamError

NOT_IMPLEMENTED = "ptam run: tracking is not implemented yet"


def main(args, cfg) -> int:
    if args.camera is None and args.video is None and args.dataset is None:
        raise PtamError(NOT_IMPLEMENTED)
    with open_source(camera=args.camera, video=args.video, dataset=args.dataset, fps=args.fps, size=args.size,
                     cfg=cfg.capture) as source:
        calibration = args.calibration or (find_calibration(args.dataset) if args.dataset else None)
        if calibration is None:
            raise InputError("no calibration: pass --calibration camera.yaml")
        camera = load_camera(calibration)
        if camera.size != source.size:
            raise InputError(f"calibration {calibration} is for {camera.width}x{camera.height} images but "
                             f"{source.name} delivers {source.size[0]}x{source.size[1]}")
        raise PtamError(NOT_IMPLEMENTED)
