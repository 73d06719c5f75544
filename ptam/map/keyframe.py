"""A keyframe's immutable data (PTAM §4).

The pose is not here: bundle adjustment moves poses all the time, so they live in ``Map.kf_T_cw``
(indexed by ``KeyFrame.id``) and a ``KeyFrame`` never changes after creation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import PtamError
from ..image.pyramid import Pyramid


@dataclass(frozen=True)
class KeyFrame:
    """``id`` is the keyframe's index in its map; ``scene_depth_mean``/``scene_depth_sigma`` are the mean and
    standard deviation of the depths of the points it measured when created (PTAM code
    ``RefreshSceneDepth``: the depth prior of the epipolar search, §6.2). ``timestamp`` is the source frame's time.
    """

    id: int
    pyramid: Pyramid
    scene_depth_mean: float
    scene_depth_sigma: float
    timestamp: float = 0.0
    panorama: bool = False  # Gauglitz et al. §4.3: added under rotation-only motion, at its SfM neighbour's centre
    part: int = 0  # Gauglitz et al. §5.3: 0 when made in this map, k ≥ 1 when it came with the k-th merged track

    @staticmethod
    def panorama_flags(keyframes) -> np.ndarray:
        """(N,) bool: which of ``keyframes`` are panorama keyframes (Gauglitz et al. §4.3)."""
        return np.array([kf.panorama for kf in keyframes], dtype=bool)

    @staticmethod
    def depth_stats(depths: np.ndarray) -> tuple[float, float]:
        """(mean, standard deviation) of measured point depths, as PTAM computes them."""
        d = np.asarray(depths, dtype=np.float64)
        if d.size == 0:
            raise PtamError("keyframe depth statistics need at least one measured point")
        return float(d.mean()), float(d.std())
