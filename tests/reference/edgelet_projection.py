"""numpy reference for ``ptam.edgelet.edgelet_projection_kernels`` (Agility §4.2 eq. 3–5, §5.1 eq. 11), built on the
numpy camera models."""

from __future__ import annotations

import numpy as np

from ptam.edgelet import perp
from ptam.edgelet.edgelet_projection_kernels import MIN_IMAGE_DIRECTION
from ptam.geometry import se3


def edgelet_projection_ref(camera, T_cw, centre, direction):
    """-> centre px, direction d, unit normal, valid, camera-frame centres and perpendicular Jacobians (N, 6)."""
    Xc = se3.transform(T_cw, centre)
    Dc = direction @ T_cw[:3, :3].T
    J = camera.project_jacobian(Xc)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = camera.project(Xc)
    d = np.einsum("nij,nj->ni", J, Dc)
    norm = np.linalg.norm(d, axis=-1)
    valid = camera.valid(Xc) & (norm > MIN_IMAGE_DIRECTION) & np.all(np.isfinite(c), axis=-1)
    n = perp(d) / np.where(norm > MIN_IMAGE_DIRECTION, norm, 1.0)[:, None]
    jac = np.einsum("ni,nij,njk->nk", n, J, se3.point_jacobian(Xc))
    return c, d, n, valid, Xc, jac
