"""Rotation error, correct fraction, glitch frames and the robust Sim(3) fit on trajectories with known
perturbations; ``score_trajectory`` with and without criteria; ``ptam eval`` prints the new fields."""

import numpy as np
import pytest

from ptam.cli import main as cli_main
from ptam.eval import write_tum
from ptam.eval.correctness import Criteria, correctness, fit_sim3, rot_rmse_deg, rotation_errors_deg
from ptam.eval.score import score_trajectory
from ptam.geometry import se3, so3

CRIT = Criteria(max_error_m=0.020, max_error_deg=2.0, gate_factor=3.0, segments=4)  # the eval config's
N = 100


def ground_truth(n=N):
    """A desk-scale camera path (about 1.5 m across) turning as it goes: timestamps (n,), T_wc (n, 4, 4)."""
    s = np.linspace(0.0, 2.0 * np.pi, n)
    xyz = np.stack([0.6 * np.cos(s), 0.4 * np.sin(2 * s), 0.5 + 0.1 * s], axis=1)
    w = np.stack([0.1 * np.sin(s), 0.8 * s, 0.05 * np.cos(3 * s)], axis=1)
    return np.arange(n) / 30.0, se3.from_Rt(so3.exp(w), xyz)


# The estimate lives in its own map frame: gt = S·est with S a similarity (scale 1/0.37, a rotation, a shift).
SCALE = 1.0 / 0.37
R_S = so3.exp(np.array([0.3, -1.1, 0.4]))
T_S = np.array([0.2, -0.5, 1.3])


def to_map(T_wc_gt):
    """Ground-truth camera-to-world poses expressed in the estimate's map frame (exact inverse of S)."""
    T = np.array(T_wc_gt, dtype=np.float64)
    T[:, :3, 3] = (T[:, :3, 3] - T_S) @ R_S / SCALE
    T[:, :3, :3] = R_S.T @ T[:, :3, :3]
    return T


def turn(T_wc, frames, deg, axis=(0.0, 0.0, 1.0)):
    """Rotate the cameras of ``frames`` by ``deg`` about a camera-frame axis."""
    T = T_wc.copy()
    a = np.asarray(axis) / np.linalg.norm(axis)
    T[frames, :3, :3] = T[frames, :3, :3] @ so3.exp(np.radians(deg) * a)
    return T


def test_rotation_error_of_a_known_turn():
    R_gt = so3.exp(np.array([[0.0, 0.0, 0.0], [0.2, 0.1, -0.3]]))
    R_est = R_gt @ so3.exp(np.array([[0.0, 0.0, np.radians(3.0)], [np.radians(0.5), 0.0, 0.0]]))
    np.testing.assert_allclose(rotation_errors_deg(R_gt, R_est, np.eye(3)), [3.0, 0.5], atol=1e-12)
    # The alignment's rotation maps estimated orientations into the ground-truth frame first.
    np.testing.assert_allclose(rotation_errors_deg(R_S @ R_gt, R_gt, R_S), [0.0, 0.0], atol=1e-12)


def test_rotation_perturbations_give_exact_errors_and_counts():
    _, T_gt = ground_truth()
    est = turn(turn(to_map(T_gt), [20, 21, 22], 3.0), list(range(30, 40)), 1.0, axis=(1.0, 2.0, -1.0))
    c = correctness(T_gt, est, N, CRIT)
    assert c.fit is not None and c.fit.used.all()
    assert c.fit.scale == pytest.approx(SCALE, rel=1e-12)
    assert np.abs(c.position_errors_m).max() < 1e-12
    expected = np.zeros(N)
    expected[[20, 21, 22]] = 3.0
    expected[30:40] = 1.0
    np.testing.assert_allclose(c.rotation_errors_deg, expected, atol=1e-9)
    # 3 frames turned by 3 degrees are glitches; 10 turned by 1 degree are within 2 degrees.
    assert (c.matched, c.correct, c.glitches) == (100, 97, 3)
    assert c.correct_fraction == pytest.approx(0.97)
    assert rot_rmse_deg(T_gt, est, c.fit.R) == pytest.approx(np.sqrt((3 * 9.0 + 10 * 1.0) / 100), rel=1e-9)


def test_untracked_frames_count_against_the_correct_fraction():
    _, T_gt = ground_truth()
    est = turn(to_map(T_gt), [20, 21, 22], 3.0)
    c = correctness(T_gt[:90], est[:90], N, CRIT)  # frames 90-99 never tracked
    assert (c.matched, c.correct, c.glitches) == (90, 87, 3)
    assert c.correct_fraction == pytest.approx(0.87)


def test_position_perturbations_split_at_the_threshold():
    _, T_gt = ground_truth()
    gt_moved = T_gt.copy()
    gt_moved[[40, 41, 42, 43], :3, 3] += [0.030, 0.0, 0.0]  # 30 mm off: glitches
    gt_moved[[60, 61], :3, 3] += [0.0, 0.0, -0.010]  # 10 mm off: still correct
    c = correctness(T_gt, to_map(gt_moved), N, CRIT)
    assert c.fit is not None and c.fit.used.all()  # nothing is beyond the 60 mm gate
    np.testing.assert_allclose(c.position_errors_m[[40, 41, 42, 43]], 0.030, atol=0.004)  # the fit gives a little
    np.testing.assert_allclose(c.position_errors_m[[60, 61]], 0.010, atol=0.004)
    assert (c.correct, c.glitches) == (96, 4)


def test_robust_fit_ignores_gross_outliers():
    _, T_gt = ground_truth()
    gt_moved = T_gt.copy()
    gt_moved[[10, 50, 80], :3, 3] += [0.7, 0.0, 0.0]  # a tracker that jumped 70 cm for three frames
    est = to_map(gt_moved)
    robust = correctness(T_gt, est, N, CRIT)
    assert robust.fit is not None
    assert np.flatnonzero(~robust.fit.used).tolist() == [10, 50, 80]
    assert robust.fit.scale == pytest.approx(SCALE, rel=1e-9)
    np.testing.assert_allclose(np.delete(robust.position_errors_m, [10, 50, 80]), 0.0, atol=1e-9)
    np.testing.assert_allclose(robust.position_errors_m[[10, 50, 80]], 0.7, atol=1e-9)
    assert (robust.correct, robust.glitches) == (97, 3)
    # Plain Umeyama (one candidate, a gate nothing fails) is dragged by the outliers: good frames up to 5 cm
    # off, most of them beyond 20 mm.
    plain = correctness(T_gt, est, N, Criteria(CRIT.max_error_m, CRIT.max_error_deg, gate_factor=1e9, segments=1))
    assert plain.fit is not None and plain.fit.used.all()
    assert plain.correct < 50
    # Outliers of 2 m drag the first fit so far that most good frames miss the gate too; the re-fit on those
    # that pass is still exact.
    gt_moved[[10, 50, 80], :3, 3] += [1.3, 0.0, 0.0]
    far = correctness(T_gt, to_map(gt_moved), N, CRIT)
    assert far.fit is not None and not far.fit.used[[10, 50, 80]].any() and far.fit.used.sum() >= 3
    assert far.fit.scale == pytest.approx(SCALE, rel=1e-9)
    assert (far.correct, far.glitches) == (97, 3)
    # The fit alone: the same three frames are left out, with or without candidate fits on parts.
    for segments in (1, 4):
        fit = fit_sim3(T_gt, est, Criteria(CRIT.max_error_m, CRIT.max_error_deg, CRIT.gate_factor, segments))
        assert np.flatnonzero(~fit.used).tolist() == [10, 50, 80]


def test_a_map_broken_part_way_keeps_its_right_part():
    """Frames 0-59 tracked right, then the map broke: frames 60-99 tracked on in a map frame turned by 20 degrees,
    shifted and scaled by 1.3 (a consistent trajectory, but all of it wrong). A fit on all frames fits neither
    part; the candidate fit on a part of the first 60 frames finds them."""
    _, T_gt = ground_truth()
    est = to_map(T_gt)
    wrong = np.arange(60, 100)
    jump = so3.exp(np.array([0.0, 0.0, np.radians(20.0)]))
    est[wrong, :3, 3] = 1.3 * est[wrong, :3, 3] @ jump.T + [0.3, 0.0, 0.0]
    est[wrong, :3, :3] = jump @ est[wrong, :3, :3]
    broken = correctness(T_gt, est, N, CRIT)
    assert broken.fit is not None and broken.fit.used.tolist() == [True] * 60 + [False] * 40
    assert broken.fit.scale == pytest.approx(SCALE, rel=1e-9)
    np.testing.assert_allclose(broken.position_errors_m[:60], 0.0, atol=1e-9)
    np.testing.assert_allclose(broken.rotation_errors_deg[:60], 0.0, atol=1e-9)
    assert (broken.correct, broken.glitches) == (60, 40)
    # The fit on all frames alone (segments 1) is dragged between the two parts: few frames come out right.
    plain = correctness(T_gt, est, N, Criteria(CRIT.max_error_m, CRIT.max_error_deg, CRIT.gate_factor, segments=1))
    assert plain.correct < 30
    # Positions that fit a similarity are not enough: the same broken part with its orientations left alone
    # (20 degrees off under the positions' alignment) supports no candidate of its own.
    est[wrong, :3, :3] = to_map(T_gt)[wrong, :3, :3]
    assert correctness(T_gt, est, N, CRIT).fit.used.tolist() == [True] * 60 + [False] * 40


def test_too_few_poses_cannot_be_judged():
    _, T_gt = ground_truth()
    c = correctness(T_gt[:2], to_map(T_gt[:2]), N, CRIT)
    assert c.fit is None and (c.matched, c.correct, c.glitches) == (2, 0, 0)
    assert np.isnan(c.rotation_errors_deg).all()


def test_score_trajectory_with_and_without_criteria(tmp_path):
    t, T_gt = ground_truth()
    gt_file = tmp_path / "gt.txt"
    write_tum(gt_file, t, T_gt)
    est = turn(to_map(T_gt), [5, 6], 4.0)
    traj = [(float(t[i]), est[i]) for i in range(N) if i % 10 != 9]  # every tenth frame untracked
    s = score_trajectory(gt_file, traj, criteria=CRIT)
    assert (s.matched, s.n_groundtruth, s.correct, s.glitches) == (90, 100, 88, 2)
    assert s.tracked_fraction == pytest.approx(0.9) and s.correct_fraction == pytest.approx(0.88)
    assert s.ate_rmse_m < 1e-9
    assert s.rot_rmse_deg == pytest.approx(np.sqrt(2 * 16.0 / 90), rel=1e-6)
    plain = score_trajectory(gt_file, traj)  # the existing call: ATE and tracked fraction as before
    assert (plain.matched, plain.correct, plain.glitches) == (90, None, None)
    assert np.isnan(plain.correct_fraction)
    assert plain.ate_rmse_m == s.ate_rmse_m and plain.rot_rmse_deg == s.rot_rmse_deg
    empty = score_trajectory(gt_file, [], criteria=CRIT)
    assert (empty.matched, empty.correct, empty.glitches) == (0, 0, 0) and np.isnan(empty.rot_rmse_deg)


def test_a_run_that_never_built_a_map_scores_without_an_ate(tmp_path):
    """Poses reported before the map exists are rotation-only at its origin: no scale fits them, so there is no
    ATE (it raised, and stopped ``ptam bench accuracy`` on a scene that never initialised). They are still judged:
    the camera of ``ground_truth`` travels a metre and more while the poses say it stayed at one point, so no
    alignment puts more than a frame or two within 20 mm of the truth: the rest are glitches."""
    t, T_gt = ground_truth()
    gt_file = tmp_path / "gt.txt"
    write_tum(gt_file, t, T_gt)
    at_origin = to_map(T_gt)
    at_origin[:, :3, 3] = 0.0
    s = score_trajectory(gt_file, [(float(t[i]), at_origin[i]) for i in range(40)], criteria=CRIT)
    assert np.isnan(s.ate_rmse_m) and np.isnan(s.rot_rmse_deg)
    assert s.matched == 40 and s.correct + s.glitches == 40 and s.glitches >= 38


def test_rotation_only_poses_are_judged_by_orientation_and_by_how_far_the_camera_moved():
    """A camera turning in place (3 mm of hand jitter) tracked by rotation-only poses at one point: every frame is
    correct, but for the five whose orientation is 3 degrees off; once the real camera drifts 50 mm off the spot,
    its frames are glitches however right their orientation."""
    rng = np.random.default_rng(7)
    _, T_gt = ground_truth()
    T_gt[:, :3, 3] = np.array([0.1, 0.2, 0.5]) + rng.uniform(-0.003, 0.003, (N, 3))
    est = turn(to_map(T_gt), [40, 41, 42, 43, 44], 3.0)
    est[:, :3, 3] = 0.0
    c = correctness(T_gt, est, N, CRIT)
    assert (c.correct, c.glitches) == (95, 5)
    np.testing.assert_allclose(c.rotation_errors_deg[40:45], 3.0, atol=0.2)  # the fit leans a little towards them
    assert np.delete(c.rotation_errors_deg, range(40, 45)).max() < 0.2
    assert c.position_errors_m.max() < 0.006  # m: the jitter about the mean
    T_gt[70:, 0, 3] += 0.05
    assert correctness(T_gt, est, N, CRIT).glitches == 5 + 30


def test_ptam_eval_prints_rotation_correctness_and_glitches(tmp_path, capsys):
    t, T_gt = ground_truth()
    gt_file, est_file = tmp_path / "gt.txt", tmp_path / "est.txt"
    write_tum(gt_file, t, T_gt)
    est = turn(to_map(T_gt), [20, 21, 22], 3.0)
    write_tum(est_file, t[:90], est[:90])
    code = cli_main(["eval", str(gt_file), str(est_file)])
    lines = capsys.readouterr().out.strip().splitlines()
    assert code == 0
    fields = dict(kv.split("=") for kv in lines[-1].split())
    assert list(fields)[:5] == ["ate_rmse_m", "scale", "matched", "tracked_fraction", "path_length_m"]
    assert list(fields)[5:] == ["rot_rmse_deg", "correct_fraction", "glitches"]
    assert float(fields["rot_rmse_deg"]) == pytest.approx(np.sqrt(3 * 9.0 / 90), rel=1e-6)
    assert float(fields["correct_fraction"]) == pytest.approx(0.87)
    assert int(fields["glitches"]) == 3
    assert any(line.startswith("rotation after Sim(3): rmse") for line in lines)
    assert any("87 of 100 ground-truth poses" in line and "glitches (tracked but wrong): 3" in line for line in lines)
    # Looser thresholds on the command line: the 3-degree frames become correct.
    code = cli_main(["eval", str(gt_file), str(est_file), "--correct-mm", "50", "--correct-deg", "5"])
    fields = dict(kv.split("=") for kv in capsys.readouterr().out.strip().splitlines()[-1].split())
    assert (code, float(fields["correct_fraction"]), int(fields["glitches"])) == (0, pytest.approx(0.9), 0)
    assert cli_main(["eval", str(gt_file), str(est_file), "--correct-mm", "0"]) == 2
    assert "--correct-mm and --correct-deg must be positive" in capsys.readouterr().err
