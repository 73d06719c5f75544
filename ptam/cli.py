"""The ``ptam`` command: run, synth, eval, bench, calibrate.

Bad input raises :class:`ptam.errors.PtamError` anywhere below; ``main`` prints it as one line on stderr
and exits 2. Subcommand implementations are imported lazily so ``ptam --help`` stays fast.
"""

from __future__ import annotations

import argparse
import sys

from .commands.bench import BENCHMARKS
from .errors import PtamError
from .vocabulary import ArScene, LensModel, RunMode, choices


def _add_config_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--config",
        action="append",
        default=[],
        metavar="FILE",
        help="YAML file overlaid on configs/default.yaml (repeatable)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        dest="overrides",
        metavar="SECTION.KEY=VALUE",
        help="override one config value, e.g. --set tracker.max_patches=500 (repeatable)",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ptam", description="Parallel Tracking and Mapping in Python.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for add in (_add_run, _add_synth, _add_eval, _add_bench, _add_calibrate):
        _add_config_args(add(sub))
    return parser


def _add_run(sub) -> argparse.ArgumentParser:
    run = sub.add_parser("run", help="track a camera, video or dataset and build a map")
    src = run.add_mutually_exclusive_group()
    src.add_argument(
        "--camera",
        metavar="v4l2[:DEVICE]|dc1394[:N|GUID]",
        help="live camera: v4l2, v4l2:/dev/video1 (UVC) or dc1394, dc1394:1 (FireWire IIDC)",
    )
    src.add_argument("--video", metavar="FILE", help="a video file")
    src.add_argument("--dataset", metavar="DIR", help="TUM RGB-D, EuRoC or a folder of images")
    run.add_argument("--calibration", metavar="CAMERA.yaml", help="camera calibration (default: DIR/camera.yaml)")
    run.add_argument("--fps", type=float, help="frame rate for image folders / requested camera rate")
    run.add_argument("--size", metavar="WxH", help="requested live camera size, e.g. 640x480")
    run.add_argument("--mode", choices=choices(RunMode), help="threading mode (default: async; realtime for --camera)")
    run.add_argument("--init-frames", metavar="A,B", help="take the stereo-initialisation keyframes at frames A and B")
    run.add_argument("--trajectory", metavar="FILE", help="write the camera trajectory (TUM format)")
    run.add_argument("--keyframes", metavar="FILE", help="write keyframe poses (TUM format)")
    run.add_argument("--map", metavar="FILE", help="write the map (reload it with --load-map)")
    run.add_argument("--load-map", metavar="FILE", help="start from a map written by --map and relocalise into it")
    run.add_argument(
        "--localize-only", action="store_true", help="with --load-map: track against the map without adding keyframes"
    )
    run.add_argument("--rrd", metavar="FILE", help="record the viewer's data to a rerun .rrd file")
    run.add_argument("--serve", action="store_true", help="serve the web viewer on 127.0.0.1 (kept until Ctrl-C)")
    run.add_argument("--no-viewer", action="store_true", help="do not open a viewer (log nothing)")
    run.add_argument(
        "--ar", choices=choices(ArScene), help="AR scene on the dominant plane (PTAM §7.5; default: config ar.scene)"
    )
    run.add_argument(
        "--ar-video", metavar="FILE", help="write the augmented frames, one per tracked frame (.avi or .mp4)"
    )
    return run


def _add_synth(sub) -> argparse.ArgumentParser:
    synth = sub.add_parser("synth", help="render a synthetic sequence with ground truth")
    synth.add_argument("scene", nargs="?", help="scene YAML file or bundled scene name")
    synth.add_argument("out", nargs="?", help="output directory")
    synth.add_argument("--list", action="store_true", help="list the bundled scenes")
    synth.add_argument("--video", action="store_true", help="also write video.avi (FFV1)")
    synth.add_argument("--contact-sheet", metavar="PNG", help="also write a grid of 12 frames (as docs/images)")
    return synth


def _add_eval(sub) -> argparse.ArgumentParser:
    ev = sub.add_parser("eval", help="compare an estimated trajectory with ground truth (ATE after Sim(3))")
    ev.add_argument("groundtruth", metavar="GT.txt")
    ev.add_argument("estimate", metavar="EST.txt")
    ev.add_argument("--max-dt", type=float, help="association tolerance in seconds (default: eval.max_time_diff_s)")
    ev.add_argument("--se3", action="store_true", help="also report ATE after SE(3) (no scale) alignment")
    ev.add_argument(
        "--correct-mm",
        type=float,
        help="a pose is correct within this many mm after alignment (default: eval.correct_mm)",
    )
    ev.add_argument("--correct-deg", type=float, help="... and within this many degrees (default: eval.correct_deg)")
    return ev


def _add_bench(sub) -> argparse.ArgumentParser:
    bench = sub.add_parser("bench", help="measure tracking and bundle-adjustment timings (PTAM Tables 1-2)")
    bench.add_argument("what", nargs="?", default="all", choices=["all", "ba", *BENCHMARKS])
    bench.add_argument(
        "scene", nargs="?", help="a scene name or file (default: two_wall; accuracy: suite, its whole scene suite)"
    )
    return bench


def _add_calibrate(sub) -> argparse.ArgumentParser:
    cal = sub.add_parser("calibrate", help="fit a camera model to chessboard views, write camera.yaml")
    cal_src = cal.add_mutually_exclusive_group()
    cal_src.add_argument("--video", metavar="FILE", help="a video of the board")
    cal_src.add_argument(
        "--camera", metavar="v4l2[:DEVICE]|dc1394[:N|GUID]", help="live camera; Ctrl-C ends the capture"
    )
    cal_src.add_argument("--images", metavar="DIR", help="a folder of images (or a TUM / EuRoC dataset)")
    cal.add_argument("--board", default="9x6", help="inner corners, e.g. 9x6")
    cal.add_argument("--square", type=float, default=0.04, help="square size in metres")
    cal.add_argument(
        "--model",
        choices=choices(LensModel),
        default=LensModel.FOV,
        help="fov = PTAM's ATAN model (default), radtan = OpenCV k1 k2 p1 p2 k3, pinhole",
    )
    cal.add_argument("-o", "--output", default="camera.yaml", help="camera file to write (default: camera.yaml)")
    return cal


def _not_implemented(name: str):
    def handler(args) -> int:
        raise PtamError(f"ptam {name}: not implemented yet")

    return handler


def _dispatch(args) -> int:
    from .config import load_config

    cfg = load_config(args.config, args.overrides)
    if args.command == "run":
        from .commands.run import main as run_main

        return run_main(args, cfg)
    if args.command == "eval":
        from .commands.evaluate import main as eval_main

        return eval_main(args, cfg)
    if args.command == "synth":
        from .commands.synth import main as synth_main

        return synth_main(args, cfg)
    if args.command == "bench":
        from .commands.bench import main as bench_main

        return bench_main(args, cfg)
    if args.command == "calibrate":
        from .commands.calibrate import main as calibrate_main

        return calibrate_main(args, cfg)
    return _not_implemented(args.command)(args)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        return _dispatch(args)
    except PtamError as e:
        print(f"ptam: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("ptam: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
