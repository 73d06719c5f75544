"""§4.3's second target keyframe for new edgelets: "For any two keyframes chosen as source and target keyframes,
there exists with high likelihood a set of edgelets which cannot be successfully triangulated due to the aperture
problem (for example if the edgelets are parallel to the camera translation between the two views). Such
incompatibility is detected, and triangulation of these edgelets is attempted again with a different, more
orthogonally translated, keyframe." The edgelet job (``edgelet_mapping``) runs its steps 3-5 again with the
keyframe found here, on the candidates it frees (the test per keyframe and candidate: ``edgelet_aperture_kernels``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..edgelet import LineMeasurements
from ..geometry import se3
from .edgelet_aperture_kernels import aperture_free, aperture_problem

if TYPE_CHECKING:
    from ..camera.model import CameraModel
    from ..config import EdgeletConfig
    from ..map.map import Map


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
    half = 0.5 * e.length_px * b
    xy = camera.unproject(np.stack([src.a - half, src.a + half, src.a], axis=1).reshape(-1, 2)).reshape(-1, 3, 2)
    P = np.concatenate([xy, np.ones(xy.shape[:2] + (1,))], axis=2) * depth
    D = (P[:, 1] - P[:, 0]) / np.linalg.norm(P[:, 1] - P[:, 0], axis=1, keepdims=True)
    Xk = np.ascontiguousarray(P[:, 2])
    C = se3.transform(T[k], m.camera_centres)  # every keyframe's centre in k's frame
    min_sin = float(np.sin(np.deg2rad(e.triangulate_min_plane_angle_deg)))
    failed = np.flatnonzero(aperture_problem(Xk, D, C[t : t + 1], min_sin)[0])
    js = m.keyframes_with_baseline(k, (t,))  # nearest first
    if len(failed) == 0 or len(js) == 0:
        return -1, failed[:0]
    T_jk = T[js] @ se3.inv(T[k])
    free = aperture_free(
        camera.kernel_params(),
        T_jk,
        C[js],
        Xk[failed],
        D[failed],
        min_sin,
        float(e.candidate_border_px),
        camera.width,
        camera.height,
    )
    count = free.sum(axis=1)
    best = int(np.argmax(count))  # the most freed, the nearest of equals
    if count[best] == 0:
        return -1, failed[:0]
    return int(js[best]), failed[free[best]]
