"""``ptam bench ar``: what the AR overlay (PTAM §7.5) costs per frame at 640×480.

The system tracks the first ``frames`` frames of the scene (sync mode) and every tracked frame's image and pose
is kept; then each AR scene is rendered over those frames in turn — plane, scene logic, grid, ray-cast spheres
and decals, screen cross-hair — timing ``Augmenter.augment`` alone (the AR worker's cost; the tracker only
enqueues), as the AR worker draws (a grey frame with a grey overlay stays grey). A warm-up frame excludes numba
compilation. Wall-clock time is the figure; the thread's CPU time is shown next to it because on a loaded machine
the wall clock also counts time spent waiting for a core. The JPEG encoding of each drawn frame for the viewer
(``camera/augmented``) and the video encoder's cost per frame are shown apart: they run in the same worker thread
but are not rendering.

Then what the AR view costs the tracker: the same frames tracked again (sync) without a viewer, then with a viewer
recording to a temporary .rrd, once without AR and once per AR scene shown in it (the AR worker's frames logged as
``camera/augmented``, as in ``ptam run``: drawn at most ``viewer.ar_max_fps`` times a second); the tracker's median
ms per frame for each, the augmented frames drawn, the frames the viewer or the AR worker had no time for, and the
AR worker's CPU time per tracked frame (what it takes from the cores the tracker and mapper share; unlike the
tracker's median it hardly depends on what else the machine runs).

Sync replay keeps both cores busy, so there every millisecond the AR worker draws is taken from the tracker or
the mapper. A live camera delivers frames at its rate and the tracker idles between them: the last rows replay
the frames in ``realtime`` mode (paced at the sequence's rate, as a camera delivers them), alternating the AR view
off and on ``realtime_runs`` times, and give each setting's median of the runs' tracker medians with their range,
so the difference can be read against the run-to-run noise.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from ..ar import SCENES, Augmenter, attach
from ..ar.layer import frame_image
from ..ar.video_writer import FOURCC, open_video_writer
from ..camera import load_camera
from ..capture import open_dataset
from ..capture.realtime import RealtimeFeed
from ..errors import InputError
from ..synthetic import ensure_sequence
from ..system import System
from ..viz.sinks import open_recording
from ..viz.viewer import Viewer
from ..vocabulary import ArScene, RunMode

RENDER_BUDGET_MS = 5.0  # issue 9: the overlay must cost less than 5 ms per frame at 640x480


def _tracked_frames(cfg, seq: Path, frames: int):
    camera = load_camera(seq / "camera.yaml")
    kept = []

    def keep(outcome, system):
        if outcome.T_cw is not None:
            kept.append((frame_image(outcome.frame), outcome.T_cw.copy(), outcome.timestamp))

    with open_dataset(seq, cfg.capture.default_fps) as src, System(camera, cfg, mode=RunMode.SYNC) as system:
        system.observers.append(keep)
        for frame in src:
            if frame.index >= frames:
                break
            system.process(frame)
        snapshot = system.mapper.snapshot
    return camera, kept, snapshot


def _scene_row(cfg, camera, name: str, kept) -> tuple[dict, np.ndarray]:
    """Scene ``name`` drawn over every kept frame as the AR worker draws it: ms per frame (wall and thread CPU)
    and the CPU time of its JPEG for the viewer; and the last frame drawn."""
    aug = Augmenter(camera, cfg, name)
    aug.augment(*kept[0][:2], kept[0][2] - 1.0, grey_ok=True)  # compile / warm caches
    ms, cpu, jpeg = [], [], []
    for image, T_cw, t in kept:
        t0, c0 = time.perf_counter(), time.thread_time()
        last = aug.augment(image, T_cw, t, grey_ok=True)
        ms.append(1e3 * (time.perf_counter() - t0))
        c1 = time.thread_time()
        cpu.append(1e3 * (c1 - c0))
        cv2.imencode(".jpg", last, [cv2.IMWRITE_JPEG_QUALITY, cfg.viewer.jpeg_quality])
        jpeg.append(1e3 * (time.thread_time() - c1))
    ms = np.array(ms)
    row = dict(
        mean=float(ms.mean()),
        median=float(np.median(ms)),
        p95=float(np.percentile(ms, 95)),
        max=float(ms.max()),
        cpu_mean=float(np.mean(cpu)),
        jpeg_cpu_mean=float(np.mean(jpeg)),
    )
    return row, last


def run_ar_benchmark(cfg, scene: str = "two_wall", out=print, frames: int = 200, realtime_runs: int = 3) -> dict:
    """Render every AR scene over the tracked frames; print ms per frame and the summary line; return them."""
    if frames < 2:
        raise InputError(f"bench ar: frames must be at least 2, got {frames}")
    seq = ensure_sequence(scene, cfg.synthetic)
    out(f"tracking {scene} frames 0-{frames - 1} (sync) ...")
    camera, kept, snapshot = _tracked_frames(cfg, seq, frames)
    if len(kept) < 2:
        raise InputError(f"bench ar: only {len(kept)} frames of {scene} were tracked")
    out(
        f"AR overlay cost per frame, {len(kept)} tracked frames at {camera.width}x{camera.height}, map of "
        f"{snapshot.n_points} points (budget {RENDER_BUDGET_MS:g} ms)"
    )
    out(
        f"{'scene':<10}{'mean (ms)':>11}{'median (ms)':>13}{'p95 (ms)':>10}{'max (ms)':>10}{'CPU mean (ms)':>15}"
        f"{'JPEG CPU (ms)':>15}"
    )
    rows = {}
    last = None
    for name in (s for s in SCENES if s != ArScene.OFF):
        rows[name], last = _scene_row(cfg, camera, name, kept)
        r = rows[name]
        out(
            f"{name:<10}{r['mean']:>11.2f}{r['median']:>13.2f}{r['p95']:>10.2f}{r['max']:>10.2f}{r['cpu_mean']:>15.2f}"
            f"{r['jpeg_cpu_mean']:>15.2f}"
        )
    if last.ndim == 2:
        last = cv2.cvtColor(last, cv2.COLOR_GRAY2BGR)  # the video is BGR
    encode = {}
    with tempfile.TemporaryDirectory() as tmp:
        for suffix, codec in FOURCC.items():
            writer = open_video_writer(Path(tmp) / f"bench{suffix}", camera.size, 30.0)
            t0 = time.perf_counter()
            for _ in range(len(kept)):
                writer.write(last)
            encode[codec] = 1e3 * (time.perf_counter() - t0) / len(kept)
            writer.release()
    out(
        "video encoding (worker thread, not rendering): "
        + ", ".join(f"{codec} {v:.2f} ms" for codec, v in encode.items())
    )
    viewer_rows = _viewer_rows(cfg, seq, frames, out)
    live_rows = _realtime_rows(cfg, seq, frames, realtime_runs, out)
    worst = max(r["mean"] for r in rows.values())
    result = dict(ar_render_ms=worst)
    out(f"ar_render_ms={worst:.2f}")
    return {
        **result,
        "scenes": rows,
        "encode_ms": encode,
        "frames": len(kept),
        "viewer": viewer_rows,
        "realtime": live_rows,
    }


def _track_with_viewer(
    cfg, seq: Path, frames: int, viewer: bool, scene: str | None, mode: RunMode = RunMode.SYNC
) -> dict:
    """Track the first ``frames`` frames in ``mode``, with a viewer recording to a temporary .rrd if ``viewer`` and,
    if ``scene``, the AR worker showing augmented frames in it; the tracker's ms per frame and what was shown."""
    camera = load_camera(seq / "camera.yaml")
    ms = []
    with tempfile.TemporaryDirectory() as tmp:
        recording = open_recording(cfg.viewer, rrd=str(Path(tmp) / "bench.rrd")) if viewer else None
        view = Viewer(recording.stream, camera, cfg, augmented=scene is not None) if viewer else None
        with open_dataset(seq, cfg.capture.default_fps) as src, System(camera, cfg, mode=mode) as system:
            if view is not None:
                system.observers.append(view)
            layer = attach(system, scene, fps=src.fps) if scene is not None else None
            if layer is not None:
                layer.listeners.append(view.augmented)
            feed = RealtimeFeed(src) if mode == RunMode.REALTIME else src
            try:
                for frame in feed:
                    if frame.index >= frames:
                        break
                    result = system.process(frame).result
                    if result is not None:
                        ms.append(result.timings.total)
            finally:
                if isinstance(feed, RealtimeFeed):
                    feed.close()
                if layer is not None:
                    layer.close()
                if view is not None:
                    view.close(system)
                    recording.close()
    return dict(
        median=float(np.median(ms)),
        p95=float(np.percentile(ms, 95)),
        dropped=view.dropped if view is not None else 0,
        ar_drawn=layer.frames_rendered if layer is not None else 0,
        ar_dropped=(layer.dropped + view.ar_dropped) if layer is not None else 0,
        ar_cpu_ms=1e3 * layer.cpu_s / max(len(ms), 1) if layer is not None else 0.0,
    )


def _viewer_rows(cfg, seq: Path, frames: int, out) -> dict:
    """The tracker's median ms without a viewer, then with the viewer recording, without the AR view and with
    each scene's."""
    out(
        "tracker ms per frame (sync) without a viewer, and with the viewer recording to an .rrd without and with "
        f"the AR view (at most viewer.ar_max_fps={cfg.viewer.ar_max_fps:g} augmented frames a second)"
    )
    out(
        f"{'viewer':<8}{'AR view':<9}{'median (ms)':>12}{'p95 (ms)':>10}{'frames not shown':>18}"
        f"{'AR frames drawn':>17}{'AR frames not shown':>21}{'AR CPU (ms/frame)':>19}"
    )
    rows = {}
    scenes = [s for s in dict.fromkeys((cfg.ar.scene, ArScene.GAME)) if s != ArScene.OFF]
    for name, viewer, scene in (("none", False, None), ("off", True, None), *((str(s), True, s) for s in scenes)):
        r = rows[name] = _track_with_viewer(cfg, seq, frames, viewer, scene)
        out(
            f"{'rrd' if viewer else 'none':<8}{str(scene or ArScene.OFF):<9}{r['median']:>12.2f}{r['p95']:>10.2f}"
            f"{r['dropped']:>18d}{r['ar_drawn']:>17d}{r['ar_dropped']:>21d}{r['ar_cpu_ms']:>19.2f}"
        )
    return rows


def _realtime_rows(cfg, seq: Path, frames: int, runs: int, out) -> dict:
    """The tracker's median ms in ``realtime`` mode with the viewer recording, the AR view off and on (the config's
    scene), alternated ``runs`` times: per setting the median of the runs' medians and their range."""
    scene = cfg.ar.scene if cfg.ar.scene != ArScene.OFF else ArScene.GRID
    out(
        f"tracker ms per frame (realtime: frames paced at the sequence's rate, as a live camera delivers them), viewer "
        f"recording, AR view off and {scene} alternated {runs} times"
    )
    out(f"{'AR view':<9}{'median of medians (ms)':>24}{'range (ms)':>16}{'p95 median (ms)':>17}")
    medians: dict[str, list[dict]] = {str(ArScene.OFF): [], str(scene): []}
    for _ in range(runs):  # alternated, so a drift in the machine's speed falls on both settings
        for name in medians:
            medians[name].append(
                _track_with_viewer(cfg, seq, frames, True, None if name == ArScene.OFF else name, RunMode.REALTIME)
            )
    rows = {}
    for name, rs in medians.items():
        m = np.array([r["median"] for r in rs])
        rows[name] = dict(median=float(np.median(m)), low=float(m.min()), high=float(m.max()),
                          p95=float(np.median([r["p95"] for r in rs])))  # fmt: skip
        r = rows[name]
        span = f"{r['low']:.2f}-{r['high']:.2f}"
        out(f"{name:<9}{r['median']:>24.2f}{span:>16}{r['p95']:>17.2f}")
    return rows
