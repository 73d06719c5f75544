"""Accuracy under live conditions: initialisation beside the tracker, a motion model that knows about missed
frames, and relocalisations that are confirmed before they count (wrong poses are worse than lost frames)."""

from __future__ import annotations

import numpy as np
import pytest

from ptam.bench.accuracy import criteria
from ptam.camera import load_camera
from ptam.capture import Frame, open_dataset
from ptam.eval.score import score_trajectory
from ptam.geometry import se3
from ptam.system import System, run_dataset
from ptam.tracking.motion_model import FrameGaps, MotionModel
from ptam.vocabulary import RunMode, TrackingState
from tests.support import capture, sequence


def test_frame_gaps_count_missed_frames_from_timestamps():
    gaps = FrameGaps(window=15)
    period = 1.0 / 30.0
    stamps = [0.0, period, 2 * period, 4 * period, 5 * period, 9 * period]
    assert [gaps.frames(t) for t in stamps] == pytest.approx([1.0, 1.0, 1.0, 2.0, 1.0, 4.0])
    assert gaps.frames(9 * period) == 1.0  # a repeated timestamp is not a gap


def test_motion_model_predicts_the_whole_gap(cfg):
    model = MotionModel(cfg.tracker)
    model.velocity = np.array([0.01, 0.0, 0.0, 0.0, 0.002, 0.0])
    T = se3.exp(np.array([0.0, 0.1, 1.0, 0.0, 0.0, 0.1]))
    two = model.predict(T, frames=2.0)
    assert np.allclose(two, se3.exp(2.0 * model.velocity) @ T, atol=1e-12)
    assert np.allclose(model.predict(T), se3.exp(model.velocity) @ T, atol=1e-12)


def test_exposure_blur_is_one_frames_motion_after_a_gap(cfg):
    """Agility eq. 10's γ_C is the motion during one exposure: after missed frames the prior spans the gap (the
    rotation estimator measures all of it) but the exposure does not, nor does the rapid-motion test (per frame)."""
    model = MotionModel(cfg.tracker)
    model.velocity = np.array([0.01, 0.0, 0.0, 0.0, 0.002, 0.0])
    rotation = np.radians([0.0, 12.0, 0.0])  # 4° a frame over three frame periods
    T = np.eye(4)
    model.predict(T, rotation=rotation, frames=3.0)
    gamma = model.exposure_motion(0.5)
    assert np.allclose(gamma[3:], 0.5 * rotation / 3.0) and np.allclose(gamma[:3], 0.5 * model.velocity[:3])
    assert np.degrees(np.linalg.norm(model.prior_rotation_per_frame())) == pytest.approx(4.0)
    model.predict(T, frames=2.0)  # no estimate: the velocity, per frame whatever the gap
    assert np.allclose(model.exposure_motion(1.0), model.velocity)


@pytest.mark.slow
@pytest.mark.alone
def test_the_map_built_beside_the_tracker_poses_every_frame_it_saw(cfg):
    """In realtime mode the first map is built in a worker while frames keep arriving; every frame from the first
    keyframe on gets a pose (PnP on its trails, then tracking), as accurate as a sync run."""
    d = sequence("two_wall_short")
    camera = load_camera(d / "camera.yaml")
    states = []
    with open_dataset(d, capture().default_fps) as src, System(camera, cfg, mode=RunMode.REALTIME) as system:
        for frame in src:  # as fast as the system takes them: the worker is still building when tracking needs it
            states.append(system.process(frame).state)
    s = score_trajectory(d / "groundtruth.txt", system.trajectory)
    assert s.matched == 200  # frames seen while initialising are posed too
    assert 1e3 * s.ate_rmse_m < 3.0  # sync gives 2.0 mm on this sequence
    t = [p[0] for p in system.trajectory]
    assert t == sorted(t)  # the trajectory only grows at its end
    assert states.count(TrackingState.INITIALISING) < 200 and system.stats.init_attempts == 1


@pytest.mark.slow
def test_a_pan_into_unmapped_space_is_lost_not_wrong(cfg):
    """desk_pan turns 360 degrees from the mapped wall through three unmapped ones. PTAM alone (model selection
    off): the frames reported tracked are right (within 20 mm and 2 degrees), the ones looking at unmapped walls
    are reported lost, and the camera relocalises when the mapped wall comes back. With model selection
    (Gauglitz et al.) the unmapped walls become a panorama and every frame is tracked and right."""
    d = sequence("desk_pan")
    ptam = cfg.replace(**{"model_selection.enabled": False})
    system = run_dataset(d, ptam, mode=RunMode.SYNC)
    s = score_trajectory(d / "groundtruth.txt", system.trajectory, criteria=criteria(cfg))
    assert s.glitches == 0
    assert s.correct_fraction > 0.5  # the mapped start and the return to the front wall
    assert system.stats.relocalisations >= 1
    system = run_dataset(d, cfg, mode=RunMode.SYNC)
    s = score_trajectory(d / "groundtruth.txt", system.trajectory, criteria=criteria(cfg))
    assert s.glitches == 0 and s.correct_fraction > 0.97


@pytest.mark.slow
def test_a_turn_round_a_corner_into_unmapped_walls_stays_tracked(cfg):
    """desk_corner turns 90 degrees in 2 s into a wall never seen: the map runs out 15 frames after a keyframe, so
    PTAM's twenty-frame spacing (PTAM §6.2) loses the camera for the rest of the run (with relocalisation alone:
    a new track, Gauglitz §4.4, would map the new wall apart). A view that has travelled panorama_kf_travel from
    every keyframe takes the next keyframe as soon as the mapper has settled the last (Gauglitz et al. §4.3):
    every frame is tracked and right."""
    d = sequence("desk_corner")
    spaced = cfg.replace(**{"model_selection.turn_keyframes_unspaced": False, "tracks.new_on_loss": False})
    system = run_dataset(d, spaced, mode=RunMode.SYNC)
    s = score_trajectory(d / "groundtruth.txt", system.trajectory, criteria=criteria(cfg))
    assert s.correct_fraction < 0.5 and system.stats.lost_events >= 1
    system = run_dataset(d, cfg, mode=RunMode.SYNC)
    s = score_trajectory(d / "groundtruth.txt", system.trajectory, criteria=criteria(cfg))
    print(f"desk_corner sync: correct {s.correct_fraction:.3f}, glitches {s.glitches}, ATE {1e3 * s.ate_rmse_m:.2f} mm")
    assert s.glitches == 0 and s.correct_fraction > 0.97 and 1e3 * s.ate_rmse_m < 5.0


@pytest.mark.slow
def test_a_still_camera_waiting_to_initialise_keeps_bounded_memory(cfg):
    """Auto initialisation with a camera that never moves: trails are followed for ever, but only the last
    ``init.max_history_frames`` frames are remembered (by their trails, no image), so memory stays flat."""
    import tracemalloc

    d = sequence("two_wall_short")
    camera = load_camera(d / "camera.yaml")
    with open_dataset(d, capture().default_fps) as src:
        frame = next(iter(src))
    small = cfg.replace(**{"init.max_history_frames": 50})
    with System(camera, small, mode=RunMode.SYNC) as system:
        for i in range(60):
            system.process(Frame(i, i / 30.0, frame.image))
        tracemalloc.start()
        before = tracemalloc.get_traced_memory()[0]
        for i in range(60, 460):
            system.process(Frame(i, i / 30.0, frame.image))
        grown = tracemalloc.get_traced_memory()[0] - before
        tracemalloc.stop()
    assert not system.mapper.initialised and len(system._init.history) == 50
    assert grown < 2e6  # bytes over 400 more frames (an image is 300 kB): nothing accumulates per frame


@pytest.mark.slow
def test_blurred_frames_of_poor_quality_are_tracked_on_but_not_reported(cfg):
    """desk_blur whips the camera at up to ~50 px/frame with motion blur: the tracker's found fraction drops
    between PTAM's lost and good thresholds (poor, PTAM's "dodgy") and there it often settles on a pose that still
    finds texture but is 200-300 mm off. Reported, those poses are glitches; withheld (the default, except under
    rapid motion, Agility §8), the frames count as not tracked, the tracker goes on from them, and far fewer
    wrong poses are reported. PTAM's point tracking shows it (no edgelets, every patch searched however blurred and
    measured as if sharp, and Agility §6's least-squares rotation prior, used as §8 says): the blur-aware default
    tracks desk_blur's sweeps right and leaves no such frames (test_edgelet_tracking)."""
    d = sequence("desk_blur")
    crit = criteria(cfg)
    cfg = cfg.replace(
        **{
            "edgelets.enabled": False,
            "tracker.blur_gate_patch_widths": float("inf"),
            "tracker.smear_variance": 0.0,
            "rotation.robust": False,
            "rotation.motion_model_fallback": False,
        }
    )
    system = run_dataset(d, cfg.replace(**{"system.report_poor_poses": True}), mode=RunMode.SYNC)
    reported = score_trajectory(d / "groundtruth.txt", system.trajectory, criteria=crit)
    system = run_dataset(d, cfg, mode=RunMode.SYNC)
    withheld = score_trajectory(d / "groundtruth.txt", system.trajectory, criteria=crit)
    print(f"desk_blur sync: poor reported {reported.glitches} glitches, withheld {withheld.glitches}")
    assert reported.glitches >= 10 and withheld.glitches <= reported.glitches // 2
    assert withheld.correct_fraction > 0.75


@pytest.mark.slow
def test_integer_matches_weighted_along_their_smear_carry_points_through_desk_blur(cfg):
    """PTAM's point tracking on desk_blur's sweeps (no edgelets, every patch searched, Agility §6's least-squares
    rotation prior): its integer matches land on whichever corner a smear left, and weighted as sharp (σ = 2^level
    both ways) they put a sixth to a fifth of the frames off (measured: 78.7 % correct, 4 glitches, 23 mm; with the
    Tukey-weighted rotation prior 91.7 %, 4 glitches, 11.8 mm). With ``tracker.smear_variance`` 1/12 (the variance of a
    position uniform over the predicted smear, along it only) the same tracker keeps 96.1 % of the frames right, with
    no glitch and a 1.9 mm ATE. The failing baseline's ATE depends on the machine: the same code and packages gave
    83.9 %, 2 glitches and 4.2 mm on an AMD EPYC (znver3) where the first figures came from another machine (its
    smeared run: 96.5 %, 0 glitches, 1.5 mm), so the baseline is held to the contrast: fewer frames right, glitches,
    and at least twice the ATE."""
    d = sequence("desk_blur")
    crit = criteria(cfg)
    ptam = cfg.replace(
        **{
            "edgelets.enabled": False,
            "tracker.blur_gate_patch_widths": float("inf"),
            "tracker.smear_variance": 0.0,
            "rotation.robust": False,
            "rotation.motion_model_fallback": False,
        }
    )
    runs = {}
    for v in (0.0, 1.0 / 12.0):
        system = run_dataset(d, ptam.replace(**{"tracker.smear_variance": v}), mode=RunMode.SYNC)
        runs[v] = score_trajectory(d / "groundtruth.txt", system.trajectory, criteria=crit)
        s = runs[v]
        print(
            f"desk_blur, PTAM's search, smear variance {v:.3f}: correct {s.correct_fraction:.3f}, "
            f"{s.glitches} glitches, ATE {1e3 * s.ate_rmse_m:.1f} mm"
        )
    sharp, smeared = runs[0.0], runs[1.0 / 12.0]
    assert smeared.correct_fraction > 0.93 and smeared.glitches == 0 and smeared.ate_rmse_m < 4e-3
    assert sharp.correct_fraction < 0.85 and sharp.glitches > 0 and sharp.ate_rmse_m > 2.0 * smeared.ate_rmse_m
