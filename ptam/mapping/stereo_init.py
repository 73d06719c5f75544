"""Building the initial map from two keyframes and their trails (PTAM §6.1, code ``MapMaker::InitFromStereo``).

Each trail's end in the second keyframe is aligned to sub-pixel accuracy against the first keyframe's
unwarped patch, and a trail whose alignment does not converge is dropped (PTAM code: ``IterateSubPixToConvergence``
on the second image; the trails end at integer FAST corners, 0.29 px RMS of quantisation that would stay in
the map's first measurements). Five-point relative pose (``two_view``), its translation scaled to the assumed
10 cm baseline, the inlier
trails triangulated into level-0 points whose source is the first keyframe, both keyframes adjusted with
the first fixed, their scene depths measured, new points added by epipolar search at every level, the
whole map adjusted to convergence, and finally the dominant plane moved to z = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..map.keyframe import KeyFrame
from ..map.map import SRC_ROOT, SRC_TRACKER
from ..patch.subpix_kernels import refine_subpix
from ..patch.warp import unwarped_templates
from .dominant_plane import fit_dominant_plane, plane_aligner
from .map_maker import MapMaker
from .panorama import new_point_levels
from .two_view import InitFailure, estimate_two_view


@dataclass(frozen=True)
class StereoMap:
    """What initialisation built beyond the map: the second keyframe's pose, and for each point made from a
    trail, the trail's row in ``xy0``/``xy1`` (so frames that followed the trails can be posed on the map)."""

    T_second: np.ndarray
    trail_rows: np.ndarray
    point_ids: np.ndarray


def init_from_stereo(mm: MapMaker, first, second, xy0: np.ndarray, xy1: np.ndarray) -> StereoMap:
    """``first``/``second``: (pyramid, timestamp). Builds the map in ``mm``.

    Raises :class:`InitFailure` with the reason; the mapper's map is left empty then.
    """
    c = mm.cfg.init
    xy0 = np.asarray(xy0, np.float64)
    xy1 = np.asarray(xy1, np.float64)
    xy1, aligned = subpixel_second(first[0], second[0], xy0, xy1, mm.cfg.patch)
    sel = np.flatnonzero(aligned)
    tv = estimate_two_view(mm.camera, xy0[sel], xy1[sel], c)
    T1 = tv.T_c1c0.copy()
    T1[:3, 3] *= c.baseline_m / np.linalg.norm(T1[:3, 3])
    X = tv.X0 * (c.baseline_m / np.linalg.norm(tv.T_c1c0[:3, 3]))
    rows = sel[tv.inliers]
    a, b = xy0[rows], xy1[rows]
    n = len(X)
    poses = np.stack([np.eye(4), T1])
    meas_kf = np.repeat([0, 1], n)
    meas_pt = np.tile(np.arange(n), 2)
    res = mm.bundle.adjust(
        poses, X, meas_kf, meas_pt, np.concatenate([a, b]), np.zeros(2 * n, np.int64), np.array([True, False])
    )
    if res.failed:
        raise InitFailure("bundle adjustment of the initial pair failed")
    bad = np.zeros(n, bool)
    bad[meas_pt[res.outliers]] = True
    keep = ~bad
    if keep.sum() < c.min_inliers:
        raise InitFailure(f"too few points survive bundle adjustment ({int(keep.sum())} < {c.min_inliers})")
    poses, X, a, b, rows = res.poses, res.points[keep], a[keep], b[keep], rows[keep]

    depths = [(X @ T[2, :3] + T[2, 3]) for T in poses]
    m = mm.map
    for i, ((pyr, ts), T, z) in enumerate(zip((first, second), poses, depths)):
        mean, sigma = KeyFrame.depth_stats(z)
        m.add_keyframe(KeyFrame(i, pyr, mean, sigma, float(ts)), T)
    k = len(X)
    ids = m.add_points(X, np.broadcast_to([0.0, 0.0, -1.0], (k, 3)), 0, 0, a)
    m.add_measurements(0, ids, a, 0, SRC_ROOT)
    m.add_measurements(1, ids, b, 0, SRC_TRACKER)
    mm.wiggle_depth_normalised = c.baseline_m / m.keyframes[0].scene_depth_mean

    for level in new_point_levels(mm.cfg.image.levels):
        mm.add_some_map_points(1, level)
    mm.recent_converged = mm.full_converged = False
    for _ in range(mm.cfg.init.max_ba_rounds):
        mm.bundle_adjust(recent=False)
        if mm.full_converged:
            break

    good = ~m.bad
    plane = fit_dominant_plane(m.X[good], c.plane_inlier_distance, c.plane_ransac_iterations, c.plane_seed)
    if plane is not None:
        centre0 = np.zeros(3)
        m.transform(plane_aligner(plane, centre0))
    mm.recent_converged = True
    mm.publish()
    mm.ready = True
    return StereoMap(m.kf_T_cw[1].copy(), rows, ids)


def subpixel_second(first, second, xy0: np.ndarray, xy1: np.ndarray, patch_cfg) -> tuple[np.ndarray, np.ndarray]:
    """Level-0 trail ends ``xy1`` in ``second`` aligned to the unwarped patches of ``first`` at ``xy0``
    (PTAM code ``InitFromStereo``): refined (n, 2) and converged (n,) bool."""
    p = patch_cfg
    templates, ok = unwarped_templates(first, 0, xy0, p.size)
    refined = xy1.copy()
    aligned = np.zeros(len(xy0), bool)
    idx = np.flatnonzero(ok)
    if len(idx):
        r, conv = refine_subpix(
            second.levels,
            templates[idx],
            np.zeros(len(idx), np.int8),
            xy1[idx],
            p.subpix_iterations,
            p.subpix_converge_px,
        )
        refined[idx] = np.where(conv[:, None], r, xy1[idx])
        aligned[idx] = conv
    return refined, aligned
