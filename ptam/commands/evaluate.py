"""``ptam eval GT.txt EST.txt``: ATE after Sim(3) alignment, tracked fraction and scale (PTAM §7.3 compares
trajectories up to a similarity because a monocular map has no absolute scale); rotation RMSE under the same
alignment, and the correct fraction and glitch frames (``ptam.eval.correctness``: within ``--correct-mm`` and
``--correct-deg`` after a robust Sim(3) fit).

GT may also be a EuRoC sequence's ``mav0/state_groundtruth_estimate0/data.csv``: its body poses are taken to
the camera by the ``T_BS`` of ``mav0/cam0/sensor.yaml`` beside it (``ptam.capture.euroc_groundtruth``).

The last line printed is machine-readable and its format is fixed (new keys are only ever appended):
``ate_rmse_m=<float> scale=<float> matched=<int>/<int> tracked_fraction=<float> path_length_m=<float>
rot_rmse_deg=<float> correct_fraction=<float> glitches=<int>``.
"""

from __future__ import annotations

import os

import numpy as np

from ..capture.dataset import EUROC_CALIBRATION_FILE
from ..capture.euroc_groundtruth import body_to_camera, read_euroc_groundtruth
from ..errors import PtamError
from ..eval import associate, ate, pairs_by_time, read_tum, rpe
from ..eval.ate import MIN_POSES
from ..eval.correctness import Criteria, correctness, rotation_errors_deg


def path_length(xyz: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(xyz, axis=0), axis=1).sum())


def criteria(args, cfg) -> Criteria:
    """The correctness thresholds: ``--correct-mm`` / ``--correct-deg`` or the ``eval`` config section."""
    mm = cfg.eval.correct_mm if args.correct_mm is None else args.correct_mm
    deg = cfg.eval.correct_deg if args.correct_deg is None else args.correct_deg
    if not (mm > 0 and deg > 0):
        raise PtamError(f"--correct-mm and --correct-deg must be positive, got {mm} and {deg}")
    return Criteria(1e-3 * mm, deg, cfg.eval.align_gate_factor, cfg.eval.align_segments)


def _report_correctness(T_gt, T_est, n_gt: int, crit: Criteria, R_ate) -> tuple[float, float, int]:
    """Print rotation error and correctness; (rotation RMSE deg, correct fraction, glitches)."""
    rot = rotation_errors_deg(T_gt[:, :3, :3], T_est[:, :3, :3], R_ate)
    rot_rmse = float(np.sqrt(np.mean(rot**2)))
    print(f"rotation after Sim(3): rmse {rot_rmse:.6g} deg, median {np.median(rot):.6g} deg, max {rot.max():.6g} deg")
    c = correctness(T_gt, T_est, n_gt, crit)
    used = int(c.fit.used.sum()) if c.fit is not None else 0
    print(
        f"correct (within {1e3 * crit.max_error_m:g} mm and {crit.max_error_deg:g} deg after a robust Sim(3) fit on "
        f"{used}/{c.matched} poses): {c.correct} of {n_gt} ground-truth poses ({100 * c.correct_fraction:.1f}%); "
        f"glitches (tracked but wrong): {c.glitches}"
    )
    return rot_rmse, c.correct_fraction, c.glitches


def read_groundtruth(path: str) -> tuple[np.ndarray, np.ndarray]:
    """A TUM file, or a EuRoC ground-truth ``data.csv`` taken to its sequence's cam0 (body poses without one)."""
    if not path.endswith(".csv"):
        return read_tum(path)
    sensor = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(path))), "cam0", EUROC_CALIBRATION_FILE)
    if not os.path.isfile(sensor):
        print(f"groundtruth: no {sensor}: comparing with the body poses of {path}")
    return read_euroc_groundtruth(path, body_to_camera(sensor))


def main(args, cfg) -> int:
    max_dt = cfg.eval.max_time_diff_s if args.max_dt is None else args.max_dt
    if not max_dt >= 0:
        raise PtamError(f"--max-dt must be non-negative, got {max_dt}")
    crit = criteria(args, cfg)
    t_gt, T_gt = read_groundtruth(args.groundtruth)
    t_est, T_est = read_tum(args.estimate)
    if len(t_gt) == 0:
        raise PtamError(f"{args.groundtruth}: no poses")
    order = np.argsort(t_gt, kind="stable")
    t_gt, T_gt = t_gt[order], T_gt[order]
    n_gt = len(t_gt)
    length = path_length(T_gt[:, :3, 3])
    print(f"groundtruth: {args.groundtruth}: {n_gt} poses over {t_gt[-1] - t_gt[0]:.3f} s, path length {length:.4f} m")
    print(f"estimate:    {args.estimate}: {len(t_est)} poses")

    ig, ie = associate(t_gt, t_est, max_dt)
    matched = len(ig)
    if matched < MIN_POSES:
        raise PtamError(
            f"only {matched} poses of {args.estimate} are within {max_dt:g} s of a ground-truth "
            f"pose; need at least {MIN_POSES} (check the timestamps or --max-dt)"
        )
    print(f"matched {matched} of {n_gt} ground-truth poses within {max_dt:g} s")

    gt_xyz, est_xyz = T_gt[ig, :3, 3], T_est[ie, :3, 3]
    sim3 = ate(gt_xyz, est_xyz, with_scale=True)
    print(
        f"ATE after Sim(3): rmse {sim3.rmse:.6g} m, median {np.median(sim3.errors):.6g} m, "
        f"max {sim3.errors.max():.6g} m, scale {sim3.scale:.6g}"
    )
    if args.se3:
        se3 = ate(gt_xyz, est_xyz, with_scale=False)
        print(
            f"ATE after SE(3):  rmse {se3.rmse:.6g} m, median {np.median(se3.errors):.6g} m, "
            f"max {se3.errors.max():.6g} m"
        )
    rot_rmse, correct_fraction, glitches = _report_correctness(T_gt[ig], T_est[ie], n_gt, crit, sim3.R)
    i, j = pairs_by_time(t_gt[ig], cfg.eval.rpe_delta_s)
    if len(i):
        rel = rpe(T_gt[ig], T_est[ie], i, j, scale=sim3.scale)
        print(
            f"RPE over {cfg.eval.rpe_delta_s:g} s (Sim(3) scale): translation rmse {rel.trans_rmse:.6g} m, "
            f"rotation rmse {rel.rot_rmse_deg:.6g} deg ({rel.pairs} pairs)"
        )
    else:
        print(f"RPE over {cfg.eval.rpe_delta_s:g} s: matched poses span less than that, skipped")

    print(
        f"ate_rmse_m={sim3.rmse:.9g} scale={sim3.scale:.9g} matched={matched}/{n_gt} "
        f"tracked_fraction={matched / n_gt:.9g} path_length_m={length:.9g} rot_rmse_deg={rot_rmse:.9g} "
        f"correct_fraction={correct_fraction:.9g} glitches={glitches}"
    )
    return 0
