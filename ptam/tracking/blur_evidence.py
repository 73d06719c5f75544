"""Whether a frame's image shows motion blur (Agility §1: blur "will wipe the image clean of corner responses").

The tracker predicts blur from the camera's motion and an assumed exposure (``tracker.exposure_fraction``, Agility
eq. 10). A frame that kept at least ``tracker.blur_corner_fraction`` of the nearest keyframe's level-0 FAST corners
was exposed too briefly to blur, however fast the camera turned: a short shutter in bright light, or a low frame
rate with a normal one. Measured (level-0 corners over the nearest keyframe's, 5th-95th percentile): the blurred
scenes' rapid frames keep 2-36 %, sharp rapid frames at 10 fps 50-126 %; two_wall's texture smeared by 10 px, the
blur that a half-frame exposure gives a frame turning at the rapid threshold, keeps 80 %.
"""

from __future__ import annotations

import numpy as np

from ..image.pyramid import Pyramid
from ..map.snapshot import MapSnapshot


def shows_blur(pyramid: Pyramid, snapshot: MapSnapshot | None, T_cw: np.ndarray, fraction: float) -> bool:
    """Whether the frame of ``pyramid``, near pose ``T_cw``, has fewer than ``fraction`` of the level-0 corners of
    the keyframe nearest that pose (True without keyframes: the assumed exposure stands)."""
    if snapshot is None or not snapshot.n_keyframes:
        return True
    near, _ = snapshot.nearest_keyframe(T_cw)
    corners = len(snapshot.keyframes[near].pyramid.corners[0])
    return not len(pyramid.corners[0]) >= fraction * corners
