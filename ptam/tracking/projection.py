"""Step 2 of PTAM §5: project the map's good points with the prior pose and keep the potentially visible ones."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .projection_kernels import project_map_points


@dataclass(frozen=True)
class Projection:
    """``ids`` point indices with their camera-frame positions ``Xc`` and level-0 pixels ``uv``."""

    ids: np.ndarray
    Xc: np.ndarray
    uv: np.ndarray


def project_points(cam_params, width: int, height: int, tracker_cfg, T_cw, X, ids, keep_invisible=False):
    """Project ``X[ids]`` with ``T_cw``; visibility (PTAM code ``TrackerData::Project``): in front, within
    ``valid_radius_factor`` × the image's largest radius, inside the image shrunk by ``image_margin_px``.
    Returns the visible subset, or with ``keep_invisible`` all points and the visibility mask."""
    ids = np.ascontiguousarray(ids, dtype=np.int64).view()
    ids.setflags(write=False)  # one kernel signature whether the ids come from a snapshot (read-only) or not
    Xc, uv, visible = project_map_points(
        cam_params,
        np.ascontiguousarray(T_cw, dtype=np.float64),
        X,
        ids,
        float(width),
        float(height),
        float(tracker_cfg.image_margin_px),
        float(tracker_cfg.valid_radius_factor),
    )
    if keep_invisible:
        return Projection(ids, Xc, uv), visible
    return Projection(ids[visible], Xc[visible], uv[visible])
