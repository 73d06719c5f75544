"""numpy references for ``ptam.tracking.projection_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np


def project_map_points_ref(camera, T_cw, X, idx, margin, radius_factor):
    """Numpy reference of :func:`project_map_points` on a :class:`~ptam.camera.model.CameraModel`."""
    Xc = X[idx] @ T_cw[:3, :3].T + T_cw[:3, 3]
    ok = camera.valid(Xc, radius_factor)
    uv = np.zeros((len(idx), 2))
    uv[ok] = camera.project(Xc[ok])
    visible = ok & camera.in_image(uv, margin)
    return Xc, uv, visible
