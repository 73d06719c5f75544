"""One pass of the tracker's stages (PTAM §5.2-§5.5) from one prior pose, and the candidates it searches.

The tracker runs a second pass when the rotation estimate's prior (Agility §6) leaves the frame in doubt, from PTAM's
motion-model prior (§5.2), and keeps the pass whose pose explains more of the patches it searched
(``rotation.motion_model_fallback``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..vocabulary import PoseModel
from .edgelet_tracking import EdgeletFrame
from .track_result import Batch


@dataclass
class Candidates:
    """The potentially visible points, coarsest first, and which of them a stage has taken."""

    ids: np.ndarray
    uv: np.ndarray
    level: np.ndarray
    M: np.ndarray
    taken: np.ndarray


@dataclass
class TrackingPass:
    """One pass of the stages from one prior: the pose, its measurements and what the pass decided."""

    T: np.ndarray
    batch: Batch
    did_coarse: bool
    n_visible: int
    rapid: bool
    edges: EdgeletFrame
    model: PoseModel

    @property
    def inliers(self) -> int:
        """The patches found and kept by the pose update (Tukey inliers)."""
        return int((self.batch.found() & (self.batch.weights > 0)).sum())

    @property
    def found_fraction(self) -> float:
        """The inliers over the patches searched (Gauglitz §4.3)."""
        return self.inliers / max(int(self.batch.attempted().sum()), 1)

    def holds(self, cfg) -> bool:
        """Good by PTAM's check, on at least as many inliers as a pose needs at all
        (``model_selection.min_sfm_points``): a fraction of a handful of patches decides nothing."""
        return self.good(cfg.tracker) and self.inliers >= cfg.model_selection.min_sfm_points

    def good(self, tcfg) -> bool:
        """PTAM §5.6's check, on the inliers as the tracker's quality counts them."""
        return self.found_fraction > tcfg.quality_good
