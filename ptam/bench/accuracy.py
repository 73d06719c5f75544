"""``ptam bench accuracy [SCENE|suite]``: accuracy on footage unlike two_wall, in every run mode.

Each scene of the accuracy suite (``ptam.synthetic.spec.SUITE``: desk scale, pinhole and radtan lenses,
photographic, repetitive and plain surfaces, hand-held jitter, pauses, brightness changes, noise, a 90 degree
turn, 15 fps), or one named scene, is run as ``ptam run --dataset`` runs it, in ``sync`` (deterministic),
``async`` (the mapper in its own thread) and ``realtime`` mode (frames delivered at the sequence's rate and
dropped while the tracker is busy, as from a live camera). One table: ATE after Sim(3) (mm), rotation RMSE
under the same alignment (deg), tracked fraction, correct fraction and glitch frames (``ptam.eval.correctness``
with the ``eval`` config's thresholds), frames dropped (realtime), the frame at which the map was initialised,
the first frame given a pose as it was processed (before the map: rotation-only, Gauglitz §6), and the tracker's
median / 95th percentile ms per frame. Then one machine-readable line per run. This is a measurement: nothing is
tuned per scene.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..camera import load_camera
from ..capture import open_dataset
from ..capture.realtime import RealtimeFeed
from ..eval.correctness import Criteria
from ..eval.score import Score, score_trajectory
from ..synthetic import ensure_sequence
from ..synthetic.spec import SUITE
from ..system import System
from ..vocabulary import RunMode, TrackingState

SUITE_NAME = "suite"
MODES = (RunMode.SYNC, RunMode.ASYNC, RunMode.REALTIME)
_MM = 1e3
_PERCENT = 100.0
SCENE_COLUMN = 18  # characters: the suite's names and a gap
_P95 = 95.0


@dataclass(frozen=True)
class AccuracyRun:
    scene: str
    mode: RunMode
    frames: int  # frames the system processed (fewer than the sequence's in realtime mode)
    score: Score
    dropped: int | None  # realtime mode only
    init_frame: int | None  # index of the first frame not INITIALISING; None if the map never initialised
    first_pose: int | None  # index of the first frame given a pose as it was processed (before the map, rotation-only)
    track_ms_median: float
    track_ms_p95: float
    keyframes: int
    wall_s: float

    def fields(self) -> dict:
        s = self.score
        return {
            "scene": self.scene,
            "mode": str(self.mode),
            "ate_mm": _MM * s.ate_rmse_m,
            "rot_rmse_deg": s.rot_rmse_deg,
            "tracked_fraction": s.tracked_fraction,
            "correct_fraction": s.correct_fraction,
            "glitches": s.glitches,
            "dropped": self.dropped,
            "init_frame": self.init_frame,
            "first_pose": self.first_pose,
            "track_ms_median": self.track_ms_median,
            "track_ms_p95": self.track_ms_p95,
            "keyframes": self.keyframes,
            "frames": self.frames,
        }


def criteria(cfg) -> Criteria:
    return Criteria.from_config(cfg.eval)


def _replay(seq: Path, cfg, mode: RunMode):
    """The sequence through a System as ``ptam run --dataset`` does; (system, init frame, first frame with a
    pose, dropped)."""
    camera = load_camera(seq / "camera.yaml")
    init_frame = first_pose = None
    with open_dataset(seq, cfg.capture.default_fps) as source:
        feed = RealtimeFeed(source) if mode == RunMode.REALTIME else source
        system = System(camera, cfg, mode=mode)
        try:
            with system:
                for frame in feed:
                    outcome = system.process(frame)
                    if init_frame is None and outcome.state != TrackingState.INITIALISING:
                        init_frame = int(outcome.index)
                    if first_pose is None and (outcome.T_cw is not None or outcome.panorama_T_cw is not None):
                        first_pose = int(outcome.index)
        finally:
            if isinstance(feed, RealtimeFeed):
                feed.close()
    return system, init_frame, first_pose, (feed.dropped if isinstance(feed, RealtimeFeed) else None)


def run_accuracy(cfg, scene: str, mode: RunMode) -> AccuracyRun:
    seq = ensure_sequence(scene, cfg.synthetic)
    t0 = time.perf_counter()
    system, init_frame, first_pose, dropped = _replay(seq, cfg, mode)
    wall = time.perf_counter() - t0
    score = score_trajectory(seq / "groundtruth.txt", system.trajectory, cfg.eval.max_time_diff_s, criteria(cfg))
    ms = np.asarray(system.stats.track_ms, dtype=np.float64)
    med, p95 = (float(np.median(ms)), float(np.percentile(ms, _P95))) if ms.size else (float("nan"),) * 2
    snap = system.mapper.snapshot
    kfs = snap.n_keyframes if snap is not None else 0
    return AccuracyRun(scene, mode, system.stats.frames, score, dropped, init_frame, first_pose, med, p95, kfs, wall)


def _row(r: AccuracyRun, width: int = SCENE_COLUMN) -> str:
    f = r.fields()
    dropped = "-" if r.dropped is None else str(r.dropped)
    init = "never" if r.init_frame is None else str(r.init_frame)
    pose = "never" if r.first_pose is None else str(r.first_pose)
    return (
        f"{r.scene:<{width}}{f['mode']:<10}{f['ate_mm']:>9.1f}{f['rot_rmse_deg']:>9.2f}"
        f"{_PERCENT * f['tracked_fraction']:>9.1f}{_PERCENT * f['correct_fraction']:>9.1f}{f['glitches']:>9d}"
        f"{dropped:>9}{init:>7}{pose:>7}{f['track_ms_median']:>8.1f}{f['track_ms_p95']:>8.1f}{r.keyframes:>5d}"
    )


def machine_line(r: AccuracyRun) -> str:
    def fmt(v) -> str:
        if v is None:
            return "none"
        return f"{v:.6g}" if isinstance(v, float) else str(v)

    return "accuracy " + " ".join(f"{k}={fmt(v)}" for k, v in r.fields().items())


def print_table(runs: list[AccuracyRun], cfg, out=print) -> None:
    e = cfg.eval
    out(
        f"Accuracy (ATE and rotation RMSE after Sim(3); correct = within {e.correct_mm:g} mm and "
        f"{e.correct_deg:g} deg after a robust Sim(3) fit, over all ground-truth frames; glitches = tracked frames "
        f"outside that; init = frame at which the map was initialised; pose = first frame given a pose live; "
        f"ms = tracker per frame)"
    )
    width = max([SCENE_COLUMN] + [len(r.scene) + 2 for r in runs])  # a scene file's path may be long
    out(
        f"{'scene':<{width}}{'mode':<10}{'ATE mm':>9}{'rot deg':>9}{'track %':>9}{'correct%':>9}{'glitches':>9}"
        f"{'dropped':>9}{'init':>7}{'pose':>7}{'med ms':>8}{'p95 ms':>8}{'kfs':>5}"
    )
    for r in runs:
        out(_row(r, width))


def run_accuracy_benchmark(cfg, scene: str = SUITE_NAME, out=print) -> list[AccuracyRun]:
    """Every scene of the suite (or ``scene``) in every mode; prints the table and one line per run."""
    scenes = list(SUITE) if scene == SUITE_NAME else [scene]
    for name in scenes:  # render everything first, so run times do not include rendering
        ensure_sequence(name, cfg.synthetic)
    runs = []
    for name in scenes:
        for mode in MODES:
            out(f"running {name} in {mode} mode ...")
            runs.append(run_accuracy(cfg, name, mode))
            out(f"  done in {runs[-1].wall_s:.1f} s")
    out("")
    print_table(runs, cfg, out)
    out("")
    for r in runs:
        out(machine_line(r))
    return runs
