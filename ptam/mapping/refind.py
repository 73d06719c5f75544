"""Measuring existing map points in a keyframe by warped patch search (PTAM §6.2, §6.4).

PTAM code (``MapMaker::ReFind_Common``): a point is projected into the keyframe; behind the camera, beyond
the valid radius, outside the image or with a bad warp it is never tried in that keyframe again; otherwise
its warped patch is searched at FAST corners within a very tight radius (4 px) and, above level 0, refined
to sub-pixel. Used for the points a new keyframe missed, for new points in older keyframes and for the
second chance of outlier measurements. The patch machinery is the tracker's (``ptam.tracking``): mapping
depends on it, never the other way round.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..patch.finder import PatchFinder
from ..patch.warp import patch_pixel_vectors, search_warps, template_matrices


@dataclass(frozen=True)
class Refound:
    tried: np.ndarray  # (n,) bool: could be searched at all (the rest must never be retried)
    found: np.ndarray  # (n,) bool
    xy: np.ndarray  # (n, 2) level-0 pixels where found
    level: np.ndarray  # (n,) search level


def refind_points(
    camera, cfg, finder: PatchFinder, kf_T_cw, kf_images, pyramid, T_cw, X, normal, source_kf, source_level, source_xy
) -> Refound:
    """Search the given points (arrays of length n) in the keyframe with pose ``T_cw`` and ``pyramid``."""
    n = len(X)
    Xc = X @ T_cw[:3, :3].T + T_cw[:3, 3]
    ok = (Xc[:, 2] > cfg.mapper.epipolar_min_z) & camera.valid(Xc, cfg.tracker.valid_radius_factor)
    uv = np.zeros((n, 2))
    uv[ok] = camera.project(Xc[ok])
    ok &= (uv[:, 0] >= 0) & (uv[:, 1] >= 0) & (uv[:, 0] <= camera.width) & (uv[:, 1] <= camera.height)
    level = np.full(n, -1, np.int32)
    found = np.zeros(n, bool)
    xy = np.zeros((n, 2))
    idx = np.flatnonzero(ok)
    if len(idx) == 0:
        return Refound(ok, found, xy, level)
    right, down = patch_pixel_vectors(
        camera, kf_T_cw, X[idx], normal[idx], source_kf[idx], source_level[idx], source_xy[idx]
    )
    A, lv = search_warps(camera.kernel_params(), cfg.patch, cfg.image.levels, T_cw, Xc[idx], right, down)
    level[idx] = lv
    ok[idx] &= lv >= 0
    keep = lv >= 0
    idx, A, lv = idx[keep], A[keep], lv[keep]
    if len(idx):
        m = finder.find(
            pyramid,
            kf_images,
            source_kf[idx],
            source_level[idx],
            source_xy[idx],
            template_matrices(A, lv),
            lv,
            uv[idx],
            float(cfg.mapper.refind_radius_px),
            lv > 0,
            require_converged=False,
        )
        found[idx] = m.found
        xy[idx] = m.xy
        ok[idx] &= m.attempted
    return Refound(ok, found, xy, level)
