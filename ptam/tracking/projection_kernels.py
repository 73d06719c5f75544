"""Projection of map points with a pose and the visibility decision (PTAM §5.2 eq. 1–2, §5 step 2).

PTAM code (``TrackerData::Project``): a point is potentially visible when it is in front of the camera,
its normalised radius is within ``radius_factor`` × the image's largest radius (the lens model is not
trusted beyond it), and it projects inside the image (here shrunk by ``margin`` pixels).
``project_map_points_ref`` is the numpy reference on the camera classes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project


@njit(nogil=True, cache=True)
def project_map_points(cam, T_cw, X, idx, width, height, margin, radius_factor):
    """Points ``X[idx]`` -> camera-frame Xc (n, 3), pixels uv (n, 2) and visible (n,)."""
    n = idx.shape[0]
    Xc = np.empty((n, 3))
    uv = np.zeros((n, 2))
    visible = np.zeros(n, dtype=np.bool_)
    max_r = radius_factor * cam[10]
    lo_x = margin
    lo_y = margin
    hi_x = width - 1.0 - margin
    hi_y = height - 1.0 - margin
    for k in range(n):
        i = idx[k]
        for r in range(3):
            Xc[k, r] = T_cw[r, 0] * X[i, 0] + T_cw[r, 1] * X[i, 1] + T_cw[r, 2] * X[i, 2] + T_cw[r, 3]
        z = Xc[k, 2]
        if z <= 0.0:
            continue
        if math.hypot(Xc[k, 0], Xc[k, 1]) > max_r * z:
            continue
        u, v, _ = project(cam, Xc[k, 0], Xc[k, 1], z)
        uv[k, 0] = u
        uv[k, 1] = v
        visible[k] = lo_x <= u <= hi_x and lo_y <= v <= hi_y
    return Xc, uv, visible
