"""The motion blur a point patch is expected to suffer, and the patches it hides (Agility §5.1 eq. 10, §9.3 Fig. 5).

Agility §5.1 predicts each edgelet's blur from the camera motion during the exposure, l = J γ_C (eq. 10). The
same prediction for a point, with its 2×6 projection Jacobian, is the smear of its patch in the image: the
length of J γ_C in level-0 pixels, 2^L times shorter at search level L. PTAM's patch search compares an unblurred
template by ZMSSD against a threshold; a patch smeared past its own width no longer looks like its template,
yet in the flattened, blurred image its best match often still passes the threshold, at a wrong place. On the
saccade's pans (30 px of blur) 80–100 % of the level-0 matches found that way were more than 2 px off and
pulled the pose 1–2° away; the coarser levels, where the same blur is 4–8× shorter, were right. Fig. 5's point
count falling with image motion is this: the tracker does not search the patches it cannot find
(``tracker.blur_gate_patch_widths``).
"""

from __future__ import annotations

import numpy as np

from ..camera import CameraModel
from .patch_blur_kernels import patch_blur_lengths


def patch_blur(camera: CameraModel, T_cw: np.ndarray, X: np.ndarray, w: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """Expected blur (level-0 px) of homogeneous features (X, w) (N, 3), (N,) seen from ``T_cw`` under the camera
    motion γ_C (6,) during the exposure: |∂CamProj/∂X_c · [w·I | −[X_c]×] · γ_C|; a ray (w = 0) does not move with
    the camera's translation (``patch_blur_kernels``)."""
    return patch_blur_lengths(
        camera.kernel_params(),
        np.ascontiguousarray(T_cw, dtype=np.float64),
        np.ascontiguousarray(X, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(w, dtype=np.float64).reshape(-1),
        np.ascontiguousarray(gamma, dtype=np.float64).reshape(6),
    )


def searchable(blur: np.ndarray, level: np.ndarray, patch_size: int, max_widths: float) -> np.ndarray:
    """Patches whose expected blur at their search ``level`` is at most ``max_widths`` patch widths."""
    return blur <= max_widths * patch_size * np.exp2(level)
