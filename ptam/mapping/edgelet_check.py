"""§4.3's check of new-edgelet hypotheses in a third keyframe: "Each hypothesis is now checked by attempting a
measurement in a third keyframe; a new edgelet is only added to the map if exactly one hypothesis is successfully
tested against this keyframe."

Every hypothesis of a candidate lies in the plane through the source line and k's centre. A keyframe whose centre
lies nearly in that plane sees them all on one image line, so its check passes any depth: the aperture problem of
§4.3, met by the check instead of the target. Each hypothesis is therefore checked in the keyframe nearest to k
(by camera centre; not k, not a target, not a panorama keyframe) that sees it inside its image free of the aperture
problem, by the triangulation's own gate (``edgelet_aperture_kernels.aperture_free``); where no keyframe does, in
the nearest, which still rejects hypotheses off the edge if not along it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..edgelet import Edgelets, LineMeasurements, verify_edgelets
from ..edgelet.edgelet_triangulation import Verification
from ..geometry import se3
from .edgelet_aperture_kernels import aperture_free

if TYPE_CHECKING:
    from ..camera.model import CameraModel
    from ..config import EdgeletConfig
    from ..map.map import Map


def check_keyframes(
    m: Map, camera: CameraModel, e: EdgeletConfig, k: int, targets: tuple[int, ...], ed: Edgelets
) -> np.ndarray:
    """Each hypothesis' check keyframe (``ed``: the hypotheses, world frame), as above; -1 where the map has no
    keyframe but k, the ``targets`` and panorama keyframes."""
    js = m.keyframes_with_baseline(k, targets)
    if len(ed) == 0 or len(js) == 0:
        return np.full(len(ed), -1)
    T = m.kf_T_cw
    C = se3.transform(T[k], m.camera_centres)  # every keyframe's centre in k's frame
    free = aperture_free(
        camera.kernel_params(),
        T[js] @ se3.inv(T[k]),
        np.ascontiguousarray(C[js]),
        np.ascontiguousarray(se3.transform(T[k], ed.centre)),
        np.ascontiguousarray(ed.direction @ T[k][:3, :3].T),
        float(np.sin(np.deg2rad(e.triangulate_min_plane_angle_deg))),
        float(e.candidate_border_px),
        camera.width,
        camera.height,
    )
    return js[np.argmax(free, axis=0)]  # the first free one, or the nearest where none is


def verify_in_check_keyframes(
    m: Map, camera: CameraModel, e: EdgeletConfig, checks: np.ndarray, ed: Edgelets
) -> Verification:
    """``verify_edgelets`` for each hypothesis in its keyframe ``checks[i]`` (``check_keyframes``' choice, none
    -1: the edgelet job runs only where the map has such a keyframe), one measurement call per keyframe."""
    keyframes = np.unique(checks).tolist() or [0]  # no hypotheses: one empty call gives the empty arrays
    groups = [np.flatnonzero(checks == c) for c in keyframes]
    parts = [
        verify_edgelets(camera, m.kf_T_cw[c], m.keyframes[c].pyramid.levels[0], ed.subset(sel), e)
        for c, sel in zip(keyframes, groups)
    ]
    back = np.argsort(np.concatenate(groups))

    def joined(rows):
        return np.concatenate(list(rows))[back]

    meas = LineMeasurements(
        *(joined(getattr(p.measurement, f) for p in parts) for f in LineMeasurements.__dataclass_fields__)
    )
    return Verification(
        joined(p.ok for p in parts), joined(p.distance_px for p in parts), joined(p.angle_deg for p in parts), meas
    )
