"""The scale gauge of global bundle adjustment.

Global BA holds the first keyframe fixed (PTAM §6.3, code): that fixes six of the seven degrees of freedom a
monocular map has, and the cost does not change when the whole map is scaled about the first keyframe. With points
alone Levenberg-Marquardt barely moves along that direction (desk_bricks: the keyframes' scale against the truth
stays within 0.1 % over the run); with edgelets, whose 4-DOF update cannot follow that scaling
(``bundle_gauge``), each global BA moved it by up to 0.6 %, and the frames tracked in between carry the scale of
their moment (desk_bricks: 0.4 mm ATE with points, 4.6 mm with edgelets, while the final keyframes are 0.2 mm off
either way). The LM steps of adjustments with edgelets now leave the keyframes' scale alone (``bundle_gauge``);
``hold_scale`` undoes what scale a global BA still gave the keyframes it started from (second order in the steps):
a similarity about the first keyframe's centre, which changes no residual.
"""

from __future__ import annotations

import numpy as np

from ..map.map import Map


def hold_scale(m: Map, centres_before: np.ndarray) -> float:
    """Scale the map about keyframe 0's centre so that the keyframes that existed before the adjustment (centres
    ``centres_before``, (K, 3)) keep their median distance ratio to it; returns the factor applied."""
    k = len(centres_before)
    if k < 2:
        return 1.0
    after = m.camera_centres[:k]
    d0 = np.linalg.norm(centres_before[1:] - centres_before[0], axis=1)
    d1 = np.linalg.norm(after[1:] - after[0], axis=1)
    ok = (d0 > 0) & (d1 > 0)
    if not ok.any():
        return 1.0
    factor = float(np.median(d0[ok] / d1[ok]))
    T = np.eye(4)
    T[:3, 3] = (1.0 - factor) * after[0]  # X' = c0 + factor·(X − c0)
    m.transform(T, factor)
    return factor
