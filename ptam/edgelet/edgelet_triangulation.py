"""New edgelets from two keyframes' line measurements, checked in a third (Agility §4.3).

Each keyframe's measured line (centre a, direction b, ``LineMeasurements``) back-projects to a plane through
that keyframe's camera centre. The plane contains the viewing ray of a and the ray direction's derivative
along b, so it is the plane of the measured line's tangent at a even through a distorting lens. The source
and target planes intersect in the infinite 3-D line of the edgelet; its position along that line is where
the source keyframe's ray through a meets the target plane (§4.3: "defined by its center in the source
keyframe"). Planes that meet at less than ``triangulate_min_plane_angle_deg`` are the aperture problem (the
edge is nearly parallel to the baseline): those hypotheses are flagged, to be retried with a keyframe
translated more orthogonally.

``verify_edgelets`` projects hypotheses into a third keyframe, measures them there (§4.2) and accepts those
whose measured line passes within ``verify_max_distance_px`` of the predicted centre and within
``verify_max_angle_deg`` of the predicted direction; the mapper adds an edgelet only if exactly one of a
candidate's hypotheses passes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera import CameraModel
from ..config.edgelet_section import EdgeletConfig
from .edgelet import Edgelets, perp
from .edgelet_measure import LineMeasurements, measure_in_keyframe
from .edgelet_projection import project_edgelets
from .edgelet_triangulation_kernels import plane_normals, triangulate_lines

_TANGENT_STEP_PX = 0.01  # central difference of the back-projected ray along the image line


@dataclass(frozen=True)
class Triangulation:
    """Hypotheses ``edgelets`` (N) with ``ok`` (N,) and the angle between the two planes (degrees)."""

    edgelets: Edgelets
    ok: np.ndarray
    plane_angle_deg: np.ndarray


@dataclass(frozen=True)
class Verification:
    """The third keyframe's check: ``ok`` (N,), the predicted centre's distance from the measured line (px),
    the angle between predicted and measured directions (degrees), and the measurement itself."""

    ok: np.ndarray
    distance_px: np.ndarray
    angle_deg: np.ndarray
    measurement: LineMeasurements


def line_rays(camera: CameraModel, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, 3, 3): the rays (z = 1) through each line's centre a and through a ± ε·b, from one unprojection."""
    a = np.asarray(a, dtype=np.float64).reshape(-1, 2)
    step = np.asarray(b, dtype=np.float64).reshape(-1, 2) * _TANGENT_STEP_PX
    xy = camera.unproject(np.stack([a, a + step, a - step], axis=1).reshape(-1, 2)).reshape(-1, 3, 2)
    rays = np.ones((len(a), 3, 3))
    rays[:, :, :2] = xy
    return rays


def line_planes(camera: CameraModel, T_cw: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World planes m·X = o (unit m (N, 3), o (N,)) through the camera centre and the image lines a + λb."""
    return plane_normals(np.ascontiguousarray(T_cw, dtype=np.float64), line_rays(camera, a, b))


def triangulate_edgelets(
    camera: CameraModel,
    T_src: np.ndarray,
    src: LineMeasurements,
    T_tgt: np.ndarray,
    tgt: LineMeasurements,
    cfg: EdgeletConfig,
) -> Triangulation:
    """3-D edgelets from lines measured in a source and a target keyframe (row i of each is one hypothesis)."""
    n = len(src.a)
    rays = line_rays(camera, np.concatenate([src.a, tgt.a]), np.concatenate([src.b, tgt.b]))
    centre, direction, normal, sin, s, z_tgt = triangulate_lines(
        camera.kernel_params(),
        np.ascontiguousarray(T_src, dtype=np.float64),
        rays[:n],
        np.ascontiguousarray(T_tgt, dtype=np.float64),
        rays[n:],
        perp(src.b),
    )
    angle = np.degrees(np.arcsin(np.clip(sin, 0.0, 1.0)))
    ok = src.ok & tgt.ok & (angle >= cfg.triangulate_min_plane_angle_deg) & (s > 0) & (z_tgt > 0)
    finite = np.all(np.isfinite(centre), axis=-1) & np.all(np.isfinite(normal), axis=-1)
    return Triangulation(Edgelets(centre, direction, normal), ok & finite, angle)


def verify_edgelets(
    camera: CameraModel, T_check: np.ndarray, image: np.ndarray, edgelets: Edgelets, cfg: EdgeletConfig
) -> Verification:
    """§4.3's check of hypotheses by a measurement in a third keyframe (full-size ``image``, pose ``T_check``)."""
    p = project_edgelets(camera, T_check, edgelets)
    centre = np.where(p.valid[:, None], p.centre, -1.0e6)  # invalid ones fall outside the image
    m = measure_in_keyframe(image, centre, p.direction, p.normal, cfg)
    dist = np.abs(np.sum((p.centre - m.a) * perp(m.b), axis=-1))
    cos = np.abs(np.sum(p.unit_direction * m.b, axis=-1))
    angle = np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))
    ok = p.valid & m.ok & (dist <= cfg.verify_max_distance_px) & (angle <= cfg.verify_max_angle_deg)
    return Verification(ok, dist, angle, m)
