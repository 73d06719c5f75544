"""Trajectory IO, association, ATE and RPE against known truth; ``ptam eval`` through the real CLI."""

import numpy as np
import pytest

from ptam.cli import main as cli_main
from ptam.errors import InputError, PtamError
from ptam.eval import associate, ate, pairs_by_frames, pairs_by_time, read_tum, rpe, write_tum
from ptam.geometry import se3, so3


def trajectory(n=200, rate=30.0, t0=1305031102.175304, seed=0):
    """A smooth 3-D loop with a turning camera: timestamps (n,), T_wc (n, 4, 4)."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 2.0 * np.pi, n)
    xyz = np.stack([1.5 * np.cos(s), np.sin(2 * s), 0.3 * s], axis=1) + 0.001 * rng.standard_normal((n, 3))
    w = np.stack([0.2 * np.sin(s), s, 0.1 * np.cos(3 * s)], axis=1)
    return t0 + np.arange(n) / rate, se3.from_Rt(so3.exp(w), xyz)


def random_rotation(rng):
    return so3.exp(rng.standard_normal(3))


def test_tum_round_trip(tmp_path):
    t, T = trajectory(50)
    path = tmp_path / "traj.txt"
    write_tum(path, t, T, header="written by a test")
    assert path.read_text().startswith("# written by a test\n#")
    t2, T2 = read_tum(path)
    np.testing.assert_array_equal(t2, t)
    assert np.abs(T2 - T).max() < 1e-12


def test_tum_bad_lines(tmp_path):
    path = tmp_path / "bad.txt"
    path.write_text("# comment\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n")
    with pytest.raises(InputError, match=r"bad.txt:3: expected 't tx ty tz qx qy qz qw'"):
        read_tum(path)
    path.write_text("1.0 0 0 0 0 0 0 0\n")
    with pytest.raises(InputError, match=r"bad.txt:1: zero quaternion"):
        read_tum(path)
    path.write_text("1.0 0 0 x 0 0 0 1\n")
    with pytest.raises(InputError, match=r"bad.txt:1:"):
        read_tum(path)
    with pytest.raises(InputError, match="trajectory file not found"):
        read_tum(tmp_path / "none.txt")
    # Commas and tabs as separators, as TUM's tools accept.
    path.write_text("1.5,1,2,3,0,0,0,1\n2.5\t4 5 6 0 0 1 0\n")
    t, T = read_tum(path)
    np.testing.assert_array_equal(t, [1.5, 2.5])
    np.testing.assert_array_equal(T[:, :3, 3], [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_allclose(T[1, :3, :3], np.diag([-1.0, -1.0, 1.0]), atol=1e-15)


def greedy_reference(t_a, t_b, max_dt):
    """TUM associate.py: every candidate pair, sorted by difference, taken greedily."""
    cand = sorted((abs(a - b), i, j) for i, a in enumerate(t_a) for j, b in enumerate(t_b) if abs(a - b) <= max_dt)
    used_a, used_b, pairs = set(), set(), []
    for _, i, j in cand:
        if i not in used_a and j not in used_b:
            used_a.add(i)
            used_b.add(j)
            pairs.append((i, j))
    pairs.sort(key=lambda p: t_a[p[0]])
    return [p[0] for p in pairs], [p[1] for p in pairs]


def test_association_matches_greedy_reference():
    rng = np.random.default_rng(5)
    # Ground truth at 100 Hz, a 30 Hz estimate with clock jitter and dropped frames: several candidates per pose.
    t_gt = 10.0 + np.arange(300) / 100.0 + rng.uniform(-0.001, 0.001, 300)
    t_est = 10.0 + np.arange(90) / 30.0 + rng.uniform(-0.006, 0.006, 90)
    t_est = rng.permutation(t_est[rng.random(90) > 0.1])
    for max_dt in (0.002, 0.01, 0.02):
        ia, ib = associate(t_gt, t_est, max_dt)
        ra, rb = greedy_reference(t_gt, t_est, max_dt)
        assert ia.tolist() == ra and ib.tolist() == rb
        assert np.all(np.abs(t_gt[ia] - t_est[ib]) <= max_dt)
        assert len(set(ia.tolist())) == len(ia) and len(set(ib.tolist())) == len(ib)


def test_association_recovers_jittered_copy():
    rng = np.random.default_rng(6)
    t = np.arange(100) / 30.0
    keep = np.sort(rng.choice(100, 80, replace=False))
    ia, ib = associate(t, t[keep] + rng.uniform(-0.004, 0.004, 80), 0.01)
    np.testing.assert_array_equal(ia, keep)
    np.testing.assert_array_equal(ib, np.arange(80))
    # Shifted by 15.5 frame periods: every estimate sits 16.7 ms from its nearest ground-truth pose.
    ia, ib = associate(t, t + 15.5 / 30.0, 0.01)
    assert len(ia) == 0 and len(ib) == 0


def test_ate_sim3_and_se3_known_values():
    rng = np.random.default_rng(7)
    _, T = trajectory(100)
    gt = T[:, :3, 3]
    R0, t0 = random_rotation(rng), rng.standard_normal(3)
    est = 0.37 * gt @ R0.T + t0
    res = ate(gt, est)
    assert res.rmse < 1e-9 and res.matched == 100
    assert res.scale == pytest.approx(1 / 0.37, rel=1e-9)
    np.testing.assert_allclose(res.aligned(est), gt, atol=1e-9)
    # SE(3) cannot undo a scale; a rigid copy it aligns exactly.
    assert ate(gt, est, with_scale=False).rmse > 0.1
    rigid = ate(gt, gt @ R0.T + t0, with_scale=False)
    assert rigid.rmse < 1e-9 and rigid.scale == 1.0
    # Independent noise of σ per axis survives alignment almost whole: RMSE ≈ σ√3.
    noisy = ate(gt, gt + 0.01 * rng.standard_normal(gt.shape))
    assert noisy.rmse == pytest.approx(0.01 * np.sqrt(3), rel=0.15)
    with pytest.raises(PtamError, match="at least 3"):
        ate(gt[:2], est[:2])


def test_rpe_zero_and_known_drift():
    t, T = trajectory(120)
    i, j = pairs_by_frames(len(T), 10)
    zero = rpe(T, T, i, j)
    assert zero.trans_rmse < 1e-12 and zero.rot_rmse_deg < 1e-6 and zero.pairs == 110
    # World-frame translation drift of 2 mm per frame: E's translation is R_j^T times the 20 mm drift per pair.
    k = np.arange(len(T))
    drifted = T.copy()
    drifted[:, :3, 3] += np.outer(k * 0.002, [1.0, 0.0, 0.0])
    res = rpe(T, drifted, i, j)
    np.testing.assert_allclose(res.trans_errors, 0.020, rtol=1e-9)
    assert res.trans_rmse == pytest.approx(0.020, rel=1e-9) and res.rot_rmse_deg < 1e-6
    # A camera turning about z only, with a yaw drift of 0.05° per frame: 0.5° per 10-frame pair.
    yaw = se3.from_Rt(so3.exp(np.outer(np.linspace(0, 3, len(T)), [0.0, 0.0, 1.0])), T[:, :3, 3])
    drifted = yaw.copy()
    drifted[:, :3, :3] = yaw[:, :3, :3] @ so3.exp(np.outer(np.radians(0.05 * k), [0.0, 0.0, 1.0]))
    res = rpe(yaw, drifted, i, j)
    np.testing.assert_allclose(res.rot_errors_deg, 0.5, rtol=1e-9)
    assert res.rot_rmse_deg == pytest.approx(0.5, rel=1e-9)
    # Over one second at 30 Hz the pairs are 30 frames apart; a scaled estimate is rescaled first.
    i, j = pairs_by_time(t, 1.0)
    np.testing.assert_array_equal(j - i, 30)
    assert len(i) == 120 - 30
    half = T.copy()
    half[:, :3, 3] *= 0.5
    assert rpe(T, half, i, j, scale=2.0).trans_rmse < 1e-12


def run_eval(capsys, *argv):
    code = cli_main(["eval", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out.strip().splitlines(), err


def parse_summary(line):
    fields = dict(kv.split("=") for kv in line.split())
    assert list(fields) == [
        "ate_rmse_m",
        "scale",
        "matched",
        "tracked_fraction",
        "path_length_m",
        "rot_rmse_deg",
        "correct_fraction",
        "glitches",
    ]
    return fields


def test_ptam_eval_similarity_copy_with_dropped_poses(tmp_path, capsys):
    rng = np.random.default_rng(8)
    t, T = trajectory(200)
    R0, t0 = random_rotation(rng), 5.0 * rng.standard_normal(3)
    S = se3.from_Rt(R0, t0)
    est = S @ T
    est[:, :3, 3] = 0.37 * T[:, :3, 3] @ R0.T + t0
    keep = np.sort(rng.choice(200, 180, replace=False))
    write_tum(tmp_path / "gt.txt", t, T)
    write_tum(tmp_path / "est.txt", t[keep] + rng.uniform(-0.003, 0.003, 180), est[keep])
    code, lines, err = run_eval(capsys, tmp_path / "gt.txt", tmp_path / "est.txt", "--se3")
    assert code == 0 and err == ""
    assert any(line.startswith("ATE after SE(3)") for line in lines)
    f = parse_summary(lines[-1])
    assert float(f["ate_rmse_m"]) < 1e-6
    assert float(f["scale"]) == pytest.approx(1 / 0.37, rel=1e-6)
    assert f["matched"] == "180/200"
    assert float(f["tracked_fraction"]) == pytest.approx(0.9, abs=1e-12)
    length = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1).sum()
    assert float(f["path_length_m"]) == pytest.approx(length, rel=1e-8)


def test_ptam_eval_bad_inputs(tmp_path, capsys):
    t, T = trajectory(20)
    write_tum(tmp_path / "gt.txt", t, T)
    write_tum(tmp_path / "far.txt", t + 100.0, T)
    code, _, err = run_eval(capsys, tmp_path / "gt.txt", tmp_path / "far.txt")
    assert code == 2
    assert err.count("\n") == 1 and "only 0 poses" in err and "need at least 3" in err
    code, _, err = run_eval(capsys, tmp_path / "gt.txt", tmp_path / "missing.txt")
    assert code == 2 and err.count("\n") == 1 and "trajectory file not found" in err
    # Loosening --max-dt makes the same files comparable.
    write_tum(tmp_path / "late.txt", t + 0.012, T)
    code, lines, _ = run_eval(capsys, tmp_path / "gt.txt", tmp_path / "late.txt", "--max-dt", "0.015")
    assert code == 0 and parse_summary(lines[-1])["matched"] == "20/20"
