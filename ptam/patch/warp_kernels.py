"""The affine patch warp A of PTAM §5.3 (eq. 7) and the choice of search level, for many points at once.

A maps a one-pixel displacement in the patch's source pyramid level to the displacement it produces in the
current frame's level 0. ``right_W``/``down_W`` are the world-frame displacements on the patch plane of one
source-level pixel right / down (``ptam.patch.warp.patch_pixel_vectors``); their images through the
linearised camera at the point give A's columns (PTAM code: ``CalcSearchLevelAndWarpMatrix``), so A follows
perspective, scale and the lens distortion at the point's image position.

Search level (det(A) is the level-0 area of one source pixel, det(A)/4^l its area at level l):
``RULE_CLOSEST`` (PTAM §5.3) picks l with det(A)/4^l closest to 1 on a log scale; ``RULE_PTAM_CODE`` raises l
while det(A)/4^l > det_max, as PTAM's code does. Either way the warp is rejected (level −1) when det(A)/4^l is
outside [det_min, det_max] at the chosen level or A is reflecting/degenerate.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project_jac

RULE_CLOSEST, RULE_PTAM_CODE = 0, 1
RULES = {"closest": RULE_CLOSEST, "ptam_code": RULE_PTAM_CODE}


@njit(nogil=True, cache=True, inline="always")
def _search_level(det, n_levels, det_min, det_max, rule):
    if not det > 0.0:
        return -1
    if rule == RULE_CLOSEST:
        level = int(math.floor(math.log(det) / math.log(4.0) + 0.5))
        level = min(max(level, 0), n_levels - 1)
    else:
        level = 0
        d = det
        while d > det_max and level < n_levels - 1:
            level += 1
            d *= 0.25
    d = det / 4.0**level
    if d < det_min or d > det_max:
        return -1
    return level


@njit(nogil=True, cache=True)
def warp_matrices(cam, T_cw, Xc, right_W, down_W, n_levels, det_min, det_max, rule):
    """A (n, 2, 2), det(A) (n,) and search level (n,) int32, −1 where the warp is rejected."""
    n = Xc.shape[0]
    A = np.zeros((n, 2, 2))
    det = np.zeros(n)
    level = np.full(n, -1, dtype=np.int32)
    J = np.empty((2, 3))
    dr = np.empty(3)
    dd = np.empty(3)
    for k in range(n):
        if Xc[k, 2] <= 1e-12:
            continue
        project_jac(cam, Xc[k, 0], Xc[k, 1], Xc[k, 2], J)
        for r in range(3):
            dr[r] = T_cw[r, 0] * right_W[k, 0] + T_cw[r, 1] * right_W[k, 1] + T_cw[r, 2] * right_W[k, 2]
            dd[r] = T_cw[r, 0] * down_W[k, 0] + T_cw[r, 1] * down_W[k, 1] + T_cw[r, 2] * down_W[k, 2]
        for r in range(2):
            A[k, r, 0] = J[r, 0] * dr[0] + J[r, 1] * dr[1] + J[r, 2] * dr[2]
            A[k, r, 1] = J[r, 0] * dd[0] + J[r, 1] * dd[1] + J[r, 2] * dd[2]
        det[k] = A[k, 0, 0] * A[k, 1, 1] - A[k, 0, 1] * A[k, 1, 0]
        level[k] = _search_level(det[k], n_levels, det_min, det_max, rule)
    return A, det, level
