"""Numpy reference for ``ptam.camera.camproj_kernels.undistort_points``: Gauss–Newton on the lens model's
vectorised ``distort`` and ``distort_jacobian`` over all points at once, until every residual is below ``tol``."""

import numpy as np


def undistort_ref(camera, xy_d, iters=30, tol=1e-14):
    xy_d = np.asarray(xy_d, dtype=np.float64)
    xy = xy_d.copy()
    for _ in range(iters):
        res = camera.distort(xy) - xy_d
        if np.all(np.abs(res) < tol):
            break
        J = camera.distort_jacobian(xy)
        xy = xy - np.linalg.solve(J, res[..., None])[..., 0]
    return xy
