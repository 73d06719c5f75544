"""``ptam run``: track a camera, a video or a dataset (or the embedded two-wall default) and build a map.

The viewer (rerun) opens by itself when there is a display, showing the augmented image first (``--ar``, default
``ar.scene``); ``--rrd FILE`` records instead, ``--serve`` serves the web viewer on 127.0.0.1, ``--no-viewer`` logs
nothing. Live cameras are driven from the terminal as in PTAM: space takes the two keyframes of stereo
initialisation (§6.1), ``r`` resets, ``q`` quits; ``a`` switches the AR scene, ``f`` fires. Output paths are
checked before the first frame. The trajectory is streamed to its file as the run goes (flushed every second), the
keyframes and the map are rewritten atomically every ``system.map_checkpoint_keyframes`` keyframes
(``run_outputs``), so even a SIGKILL leaves them on disk; everything is finished at the end of the stream, on
Ctrl-C, SIGTERM, SIGHUP and on errors alike (a camera that disappears, a truncated video), then a summary is
printed. An output that still cannot be written does not stop the others: exit 2 after the summary, one line
naming it. ``--load-map`` starts from a saved map;
``--localize-only`` tracks against it without mapping. A dataset that carries ``groundtruth.txt`` (TUM layout,
e.g. from ``ptam synth``) or EuRoC's ground truth is also scored: ATE after Sim(3) alignment, next to PTAM's 6 mm
on its two-wall sequence.
"""

from __future__ import annotations

import logging
import signal
import sys
import threading
import time

import numpy as np

from ..capture import find_calibration, find_groundtruth, open_source
from ..capture.keys import TerminalKeys
from ..capture.realtime import RealtimeFeed
from ..errors import InputError, PtamError
from ..eval.ate import MIN_POSES
from ..eval.correctness import Criteria
from ..eval.score import score_poses
from ..map.map_file import load_map
from ..system import System
from ..vocabulary import ArScene, InitMode, RunMode, TrackingState
from .run_camera import run_camera
from .run_outputs import RunOutputs, check_output_paths, finish_video
from .run_progress import Display
from .run_summary import print_summary

DEFAULT_SCENE = "two_wall"
PAPER_ATE_MM = 6.0  # PTAM §7.3: standard deviation from ground truth on its synthetic two-wall sequence
KEY_INIT, KEY_RESET, KEY_QUIT = " ", "r", "q"
KEY_FIRE, KEY_SCENE = "f", "a"  # the game's fire button; the next AR scene (PTAM's "Draw AR" toggle, its eyes included)
SCENE_CYCLE = (ArScene.GRID, ArScene.EYES, ArScene.GAME, ArScene.OFF)
KEYS_HELP = (
    "ptam: keys: space = stereo-initialisation keyframes (PTAM §6.1; after a loss, of a new track), r = reset, q = quit"
)
AR_KEYS_HELP = (
    "ptam: AR keys: a = next AR scene (grid, eyes = PTAM's EyeGame, game, off), "
    "f = fire in the game (aiming at a target for ar.dwell_frames frames also hits it)"
)

STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


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


def _check_arguments(args) -> None:
    if args.localize_only and not args.load_map:
        raise InputError("--localize-only needs a map to track against: add --load-map FILE")
    if args.no_viewer and (args.rrd or args.serve):
        raise InputError("--no-viewer logs nothing; leave it out to use --rrd or --serve")
    check_output_paths(args)


def _open(args, cfg, map_camera):
    dataset = args.dataset
    if args.camera is None and args.video is None and dataset is None:
        from ..synthetic import ensure_sequence

        print(
            f"ptam: no source given: replaying the embedded synthetic scene '{DEFAULT_SCENE}' (rendered once, cached)",
            file=sys.stderr,
        )
        dataset = str(ensure_sequence(DEFAULT_SCENE, cfg.synthetic))
    source = open_source(
        cfg.capture, camera=args.camera, video=args.video, dataset=dataset, fps=args.fps, size=args.size
    )
    try:
        calibration = args.calibration or (find_calibration(dataset) if dataset else None)
        camera = run_camera(calibration, map_camera, source, cfg.image)
    except BaseException:
        source.close()
        raise
    return source, camera, dataset


def _open_recording(args, cfg, live: bool):
    """The rerun recording for this run, or None (--no-viewer, or no display and nothing else asked for)."""
    if args.no_viewer:
        return None
    from ..viz.sinks import has_display, open_recording

    spawn = not (args.rrd or args.serve)
    if spawn and not has_display():
        print(
            "ptam: no display (DISPLAY/WAYLAND_DISPLAY unset): not opening the viewer; use --serve or --rrd FILE "
            "to see the run",
            file=sys.stderr,
        )
        return None
    try:
        recording = open_recording(cfg.viewer, spawn=spawn, rrd=args.rrd, serve=args.serve, live=live)
    except PtamError:
        raise
    except Exception as e:  # the viewer is optional; a run is still worth doing without it
        if not spawn:
            raise InputError(f"cannot start the viewer: {e}") from None
        print(f"ptam: cannot open the viewer ({e}); running without it", file=sys.stderr)
        return None
    print(f"ptam: {', '.join(recording.targets)}", file=sys.stderr)
    return recording


def _score(dataset: str | None, system: System, embedded: bool, cfg) -> None:
    try:
        found = find_groundtruth(dataset) if dataset else None
        if found is None:
            return
        gt, t_gt, T_gt = found
        r = score_poses(t_gt, T_gt, system.trajectory, criteria=Criteria.from_config(cfg.eval))
    except PtamError as e:  # a ground truth that cannot score the run does not fail a run that worked
        print(f"ptam: not scored against the dataset's ground truth: {e}", file=sys.stderr)
        return
    if not np.isfinite(r.ate_rmse_m):  # rotation-only poses are still judged (``eval.correctness``)
        print(
            f"ptam: no ATE against {gt}: fewer than {MIN_POSES} tracked poses in 3-D; correct "
            f"{100 * r.correct_fraction:.1f}%, glitch frames {r.glitches}",
            file=sys.stderr,
        )
        return
    paper = f" (PTAM §7.3 reports {PAPER_ATE_MM:g} mm on its two-wall sequence)" if embedded else ""
    print(
        f"ATE against {gt}: {1e3 * r.ate_rmse_m:.2f} mm RMSE after Sim(3) alignment over {r.matched}/"
        f"{r.n_groundtruth} poses, path {r.path_length_m:.2f} m{paper}; correct "
        f"{100 * r.correct_fraction:.1f}% (within {cfg.eval.correct_mm:g} mm and {cfg.eval.correct_deg:g} deg), "
        f"glitch frames {r.glitches}"
    )


def _status(system: System, outcome, feed):
    """The status line's text for the latest frame."""

    def text(fps: float) -> str:
        snap = system.mapper.snapshot
        state = str(outcome.state)
        if outcome.state == TrackingState.INITIALISING and system.init_mode == InitMode.KEY:
            state += (
                ": move the camera sideways, then press space"
                if system.init_started
                else ": press space to take the first keyframe"
            )
        kfs, pts = (snap.n_keyframes, snap.n_points) if snap is not None else (0, 0)
        dropped = f"  dropped {feed.dropped}" if isinstance(feed, RealtimeFeed) else ""
        return f"{state}  {fps:.1f} fps  kfs {kfs}  points {pts}{dropped}"

    return text


def _keys(keys: TerminalKeys, system: System, display: Display, ar=None) -> bool:
    """Act on the keys pressed since the last frame; True to quit. ``ar``: the AR layer, if any."""
    for key in keys.read().lower():
        if key == KEY_QUIT:
            return True
        if key == KEY_INIT:
            system.request_keyframe()
        elif key == KEY_RESET:
            if system.localize_only:
                display.write("ptam: reset is not available with --localize-only")
            else:
                system.reset()
                display.write("ptam: reset: the map is discarded; initialise again")
        elif key in (KEY_FIRE, KEY_SCENE):
            _ar_key(key, ar, display)
    return False


def _ar_key(key: str, ar, display: Display) -> None:
    """f fires, a switches to the next scene; both reach the AR worker, which applies them at its next frame."""
    if ar is None:
        display.write("ptam: no AR view in this run (--ar off, or no viewer and no --ar-video)")
    elif key == KEY_SCENE:
        scene = SCENE_CYCLE[(SCENE_CYCLE.index(ar.scene_name) + 1) % len(SCENE_CYCLE)]
        ar.set_scene(scene)
        display.write(f"ptam: AR scene {scene}")
    elif ar.scene_name == ArScene.GAME:
        ar.fire()
    else:
        display.write(f"ptam: f fires in the game; the AR scene is {ar.scene_name} (a switches scenes)")


def _serve_until_interrupted(recording, stop: _StopRequest) -> None:
    print(f"ptam: the run is over; the web viewer stays at {recording.server.url} until Ctrl-C", file=sys.stderr)
    try:
        while recording.server.process.poll() is None and not stop.requested:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass


class _StopRequest:
    """Ctrl-C, SIGTERM and SIGHUP (the terminal closed) during a run: the first asks it to stop after the current
    frame, so the outputs are written from a consistent state; a second one interrupts at once (e.g. a camera that
    no longer delivers)."""

    def __init__(self):
        self.requested = False
        self._previous: dict = {}

    def _handle(self, signum, frame) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True

    def __enter__(self) -> _StopRequest:
        if threading.current_thread() is threading.main_thread():
            for sig in STOP_SIGNALS:
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous = {}


def main(args, cfg) -> int:
    with _StopRequest() as stop:
        return _main(args, cfg, stop)


def _main(args, cfg, stop: _StopRequest) -> int:
    logging.basicConfig(level=logging.INFO, format="ptam: %(message)s", stream=sys.stderr)
    live = args.camera is not None
    mode = RunMode(args.mode or (RunMode.REALTIME if live else cfg.system.mode))
    init_frames = _init_frames(getattr(args, "init_frames", None))
    _check_arguments(args)
    loaded = load_map(args.load_map, cfg.image) if args.load_map else None
    embedded = args.camera is None and args.video is None and args.dataset is None
    source, camera, dataset = _open(args, cfg, loaded.camera if loaded else None)
    with source:
        recording = _open_recording(args, cfg, live)
        try:
            system, code = _run(args, cfg, source, camera, mode, init_frames, loaded, recording, live, stop)
            _score(dataset, system, embedded, cfg)
            if recording is not None and recording.server is not None and code == 0:
                _serve_until_interrupted(recording, stop)
        finally:
            if recording is not None:
                recording.close()
    return code


def _ar_scene(args, cfg, viewing: bool) -> str | None:
    """The AR scene to draw (``--ar``, default config ``ar.scene``), or None for no AR worker at all: AR is drawn
    when a viewer shows it or ``--ar-video`` writes it (``--ar off`` with a video: the plain frames)."""
    scene = args.ar or cfg.ar.scene
    if args.ar_video:
        return scene
    if scene == ArScene.OFF or not viewing:
        if args.ar not in (None, ArScene.OFF):
            print(f"ptam: --ar {args.ar}: no viewer and no --ar-video to show it; nothing is drawn", file=sys.stderr)
        return None
    return scene


def _attach_observers(args, cfg, system: System, camera, recording, fps: float):
    """The viewer (when recording) and the AR worker (when shown or written): both observe off this thread. The
    viewer's ``augmented`` is the AR worker's view: it asks for the frames the viewer has time for (at most
    ``viewer.ar_max_fps`` a second unless ``--ar-video`` has every frame drawn), which go straight to its queue."""
    scene = _ar_scene(args, cfg, recording is not None)
    shown = recording is not None and scene not in (None, ArScene.OFF)
    viewer = None
    if recording is not None:
        from ..viz.viewer import Viewer

        viewer = Viewer(recording.stream, camera, cfg, augmented=shown)
        system.observers.append(viewer)
    ar = None
    if scene is not None:
        from ..ar import attach

        ar = attach(system, scene, args.ar_video, fps)
        if shown and viewer is not None:
            ar.listeners.append(viewer.augmented)
    return viewer, ar


def _close_observers(system: System, viewer, ar) -> None:
    """The AR worker first (its last frames go to the video and the viewer), then the viewer."""
    try:
        if ar is not None:
            ar.close()  # flushes the video
    finally:
        if viewer is not None:
            viewer.close(system)
            if viewer.error is not None:
                print(f"ptam: the viewer could not log part of the run: {viewer.error}", file=sys.stderr)
            if viewer.ar_dropped:
                print(f"ptam: augmented frames not shown in the viewer: {viewer.ar_dropped}", file=sys.stderr)


def _process(system: System, feed, keys: TerminalKeys, display: Display, stop: _StopRequest, ar=None) -> bool:
    """Every frame of ``feed`` through the system, until its end, q, or a stop request; True if interrupted."""
    for frame in feed:
        outcome = system.process(frame)
        display.frame_done(_status(system, outcome, feed))
        if keys.active and _keys(keys, system, display, ar):
            return False
        if stop.requested:
            return True
    return False


def _system(args, cfg, camera, mode, init_frames, loaded, keys: TerminalKeys) -> System:
    init_mode = InitMode.KEY if keys.active and init_frames is None else InitMode.AUTO
    return System(
        camera,
        cfg,
        mode=mode,
        init_frames=init_frames,
        map_=loaded.map if loaded else None,
        localize_only=args.localize_only,
        init_mode=init_mode,
    )


def _finish(system: System, viewer, ar, outputs: RunOutputs, video: str | None) -> list[str]:
    """Close the observers and finish every output; one line per output that could not be written."""
    failures = []
    try:
        _close_observers(system, viewer, ar)
        finish_video(video)
    except (PtamError, OSError) as e:  # the AR video; the files below are still written
        failures.append(f"--ar-video {video}: {e}" if video else str(e))
    finally:
        failures += outputs.close(system)
    return failures


def _run(args, cfg, source, camera, mode, init_frames, loaded, recording, live, stop) -> tuple[System, int]:
    """Process the source to its end (or q, Ctrl-C, an input error); outputs are written whatever happens."""
    keys = TerminalKeys(sys.stdin if live else None)
    system = _system(args, cfg, camera, mode, init_frames, loaded, keys)
    outputs = RunOutputs(args, cfg, camera).start(system)
    try:
        viewer, ar = _attach_observers(args, cfg, system, camera, recording, source.fps)
    except BaseException:
        outputs.abandon()
        raise
    feed = RealtimeFeed(source) if mode == RunMode.REALTIME else source
    if system.init_mode == InitMode.KEY:
        print(KEYS_HELP, file=sys.stderr)
    if keys.active and ar is not None:
        print(AR_KEYS_HELP, file=sys.stderr)
    interrupted, error, failures = False, None, []
    try:
        with system, keys, Display(source.length, cfg.viewer.status_interval_s) as display:
            interrupted = _process(system, feed, keys, display, stop, ar)
    except KeyboardInterrupt:
        interrupted = True
    except PtamError as e:
        error = e
    finally:
        if isinstance(feed, RealtimeFeed):
            feed.close()
        failures = _finish(system, viewer, ar, outputs, args.ar_video if ar is not None else None)
    if interrupted:
        print("ptam: interrupted; wrote what was computed", file=sys.stderr)
    print_summary(system, mode, feed.dropped if isinstance(feed, RealtimeFeed) else None, viewer, outputs.checkpoints)
    if not system.mapper.initialised:
        reason = system.last_failure or "no frame gave a usable stereo pair"
        print(f"initialisation did not succeed: {reason}")
    if error is not None:
        raise error
    if failures:
        raise InputError("; ".join(failures))
    return system, 130 if interrupted else 0
