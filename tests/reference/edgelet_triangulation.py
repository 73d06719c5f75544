"""numpy references for ``ptam.edgelet.edgelet_triangulation_kernels`` (Agility §4.1, §4.3): the back-projected
line planes, their intersection and the new edgelets' frames as array operations over all hypotheses."""

from __future__ import annotations

import numpy as np

from ptam.edgelet.edgelet import Edgelets, perp
from ptam.geometry import se3

TANGENT_STEP_PX = 0.01


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _rays(camera, uv: np.ndarray) -> np.ndarray:
    xy = camera.unproject(uv)
    return np.concatenate([xy, np.ones(xy.shape[:-1] + (1,))], axis=-1)


def line_planes_ref(camera, T_cw, a, b):
    T_cw = np.asarray(T_cw, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64) * TANGENT_STEP_PX
    tangent = _rays(camera, a + b) - _rays(camera, a - b)
    m_c = np.cross(_rays(camera, a), tangent)
    m_w = m_c @ T_cw[:3, :3]
    with np.errstate(invalid="ignore"):  # a zero direction: no plane
        m_w /= np.linalg.norm(m_w, axis=-1, keepdims=True)
    return m_w, m_w @ se3.inv(T_cw)[:3, 3]


def frames_from_first_view_ref(centre_w, direction_w, T_cw, image_normal, proj_jac) -> Edgelets:
    """Edgelets whose x-axis points dark → light in the view ``T_cw`` (measured normal ``image_normal`` (N, 2),
    the camera's ∂(u, v)/∂X_c ``proj_jac`` (N, 2, 3) at the centres)."""
    R = np.asarray(T_cw, dtype=np.float64)[:3, :3]
    Xc = np.asarray(centre_w, dtype=np.float64) @ R.T + T_cw[:3, 3]
    zc = _unit(np.asarray(direction_w, dtype=np.float64)) @ R.T
    n_img = np.asarray(image_normal, dtype=np.float64)
    d_img = np.einsum("nij,nj->ni", proj_jac, zc)
    zc = zc * np.where(np.sum(perp(d_img) * n_img, axis=-1) < 0, -1.0, 1.0)[:, None]
    xc = _unit(np.cross(zc, Xc))
    x_img = np.einsum("nij,nj->ni", proj_jac, xc)
    xc = xc * np.where(np.sum(x_img * n_img, axis=-1) < 0, -1.0, 1.0)[:, None]
    return Edgelets(np.asarray(centre_w, dtype=np.float64), zc @ R, xc @ R).orthonormalised()


def triangulate_ref(camera, T_src, src_a, src_b, T_tgt, tgt_a, tgt_b):
    """(edgelets, sin of the plane angle, s along the source ray, depth in the target) of each hypothesis."""
    m1, _ = line_planes_ref(camera, T_src, src_a, src_b)
    m2, o2 = line_planes_ref(camera, T_tgt, tgt_a, tgt_b)
    D = np.cross(m1, m2)
    sin = np.linalg.norm(D, axis=-1)
    D = D / np.where(sin > 0, sin, 1.0)[:, None]
    T_ws = se3.inv(np.asarray(T_src, dtype=np.float64))
    ray = _rays(camera, src_a) @ T_ws[:3, :3].T
    C1 = T_ws[:3, 3]
    den = np.sum(ray * m2, axis=-1)
    s = (o2 - m2 @ C1) / np.where(np.abs(den) > 0, den, np.inf)
    X = C1 + s[:, None] * ray
    z_tgt = se3.transform(T_tgt, X)[:, 2]
    Xc = se3.transform(T_src, X)
    J = camera.project_jacobian(np.where(Xc[:, 2:3] > 0, Xc, 1.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        edgelets = frames_from_first_view_ref(X, D, T_src, perp(src_b), J)
    return edgelets, sin, s, z_tgt
