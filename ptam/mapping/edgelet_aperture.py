"""§4.3's second target keyframe for new edgelets: "For any two keyframes chosen as source and target keyframes,
there exists with high likelihood a set of edgelets which cannot be successfully triangulated due to the aperture
problem (for example if the edgelets are parallel to the camera translation between the two views). Such
incompatibility is detected, and triangulation of these edgelets is attempted again with a different, more
orthogonally translated, keyframe." The edgelet job (``edgelet_mapping``) runs its steps 3-5 again with the
keyframe found here, on the candidates it frees.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..edgelet import LineMeasurements
from ..geometry import se3
from ..map.keyframe import KeyFrame

if TYPE_CHECKING:
    from ..camera.model import CameraModel
    from ..config import EdgeletConfig
    from ..map.map import Map


def aperture_problem(Xk: np.ndarray, D: np.ndarray, C: np.ndarray, min_deg: float) -> np.ndarray:
    """(K, N): whether candidate n (a point ``Xk`` on its 3-D line and the line's direction ``D``, in keyframe
    k's frame) meets §4.3's aperture problem with the camera centre ``C[i]`` (k's frame): the planes through the
    line and the two centres, which triangulation intersects, meet at less than ``min_deg``
    (``edgelets.triangulate_min_plane_angle_deg``, the triangulation's own gate)."""
    n_k = np.cross(D, Xk)  # k's centre is the origin
    n_j = np.cross(D[None], Xk[None] - C[:, None, :])
    sin = np.linalg.norm(np.cross(n_k[None], n_j), axis=-1)
    norm = np.linalg.norm(n_k, axis=-1)[None] * np.linalg.norm(n_j, axis=-1)
    return sin < np.sin(np.deg2rad(min_deg)) * np.maximum(norm, np.finfo(float).tiny)


def aperture_retry(
    m: Map, camera: CameraModel, e: EdgeletConfig, k: int, t: int, src: LineMeasurements
) -> tuple[int, np.ndarray]:
    """§4.3: candidates that the aperture problem keeps from triangulating with target t are "attempted again
    with a different, more orthogonally translated, keyframe". Each candidate's 3-D line is taken at k's mean
    scene depth, facing the camera (its depth and slant are what triangulation finds). Of the other keyframes
    with a baseline (not panorama keyframes), the one that sees the most of the failed ones free of the aperture
    problem, the nearer of equals. Returns (that keyframe, the indices of the candidates it frees), or -1 and
    none."""
    T = m.kf_T_cw
    depth = m.keyframes[k].scene_depth_mean
    b = src.b / np.linalg.norm(src.b, axis=1, keepdims=True)
    ends = [src.a + s * 0.5 * e.length_px * b for s in (-1.0, 1.0)]
    P0, P1, Xk = (np.concatenate([camera.unproject(p), np.ones((len(p), 1))], axis=1) * depth for p in (*ends, src.a))
    D = (P1 - P0) / np.linalg.norm(P1 - P0, axis=1, keepdims=True)
    C = se3.transform(T[k], m.camera_centres)  # every keyframe's centre in k's frame
    min_deg = e.triangulate_min_plane_angle_deg
    failed = np.flatnonzero(aperture_problem(Xk, D, C[t : t + 1], min_deg)[0])
    others = np.ones(m.n_keyframes, bool)
    others[[k, t]] = False
    others &= ~KeyFrame.panorama_flags(m.keyframes)
    if len(failed) == 0 or not others.any():
        return -1, failed[:0]
    js = np.flatnonzero(others)
    T_jk = T[js] @ se3.inv(T[k])
    Xj = np.einsum("kij,nj->kni", T_jk[:, :3, :3], Xk[failed]) + T_jk[:, None, :3, 3]
    seen = camera.valid(Xj.reshape(-1, 3)) & camera.in_image(camera.project(Xj.reshape(-1, 3)), e.candidate_border_px)
    free = seen.reshape(len(js), len(failed)) & ~aperture_problem(Xk[failed], D[failed], C[js], min_deg)
    count = free.sum(axis=1)
    best = np.lexsort((np.linalg.norm(C[js], axis=1), -count))[0]  # the most freed, then the nearest
    if count[best] == 0:
        return -1, failed[:0]
    return int(js[best]), failed[free[best]]
