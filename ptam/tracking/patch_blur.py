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

The patches it does search can be measured with their smear in mind (``smear_axes``, an option that is off by
default). PTAM's search takes the best FAST corner in the radius, and in a smeared patch the corners sit wherever
the smear left them, anywhere along its length: on the saccade's first blurred frames the level-1 and level-2
integer matches lay 1.6-2.5 px (median) from the truth along the pan, spread by 1.7-3.4 px (median absolute
deviation), while the sub-pixel top level's median was within 0.02 px; weighted by σ = 2^level alone, the lower
levels outnumbered it and put the pose 29-70 mm off. With ``tracker.smear_variance`` v > 0 an integer match's
variance along its smear is σ² + v·|s|² (1/12: uniform over the smear), across it σ²; a sub-pixel match aligns the
whole template and keeps PTAM's σ both ways. Points alone this keeps desk_blur's sweeps right where PTAM's weights
do not (test_live_accuracy); beside edgelets, whose σ stays one pixel under blur (Agility §8), it hands them the
pose along the pan, and the default is PTAM's.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..camera import CameraModel
from ..patch.finder import PatchMatches
from .patch_blur_kernels import patch_smears


def patch_smear(camera: CameraModel, T_cw: np.ndarray, X: np.ndarray, w: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """Expected smear (N, 2), level-0 px, of homogeneous features (X, w) (N, 3), (N,) seen from ``T_cw`` under the
    camera motion γ_C (6,) during the exposure: ∂CamProj/∂X_c · [w·I | −[X_c]×] · γ_C; a ray (w = 0) does not move
    with the camera's translation (``patch_blur_kernels``)."""
    return patch_smears(
        camera.kernel_params(),
        np.ascontiguousarray(T_cw, dtype=np.float64),
        np.ascontiguousarray(X, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(w, dtype=np.float64).reshape(-1),
        np.ascontiguousarray(gamma, dtype=np.float64).reshape(6),
    )


def patch_blur(camera: CameraModel, T_cw: np.ndarray, X: np.ndarray, w: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """Expected blur (N,), level-0 px: the length of ``patch_smear``."""
    smear = patch_smear(camera, T_cw, X, w, gamma)
    return np.hypot(smear[:, 0], smear[:, 1])


def smear_axes(smear: np.ndarray, level: np.ndarray, variance: float) -> np.ndarray:
    """The pose update's smear axes a (N, 2) (``pose_kernels``) for matches of patches smeared by ``smear`` (N, 2)
    level-0 px. A smeared patch no longer has one best position along its smear: its match lies anywhere on it.
    Across the smear the measurement keeps PTAM's σ = 2^level (§5.4); along it the variance grows by
    ``variance``·|s|² (1/12: a position uniform over the smear's length). The information σ⁻²·(I − a·aᵀ) is that
    covariance's inverse when a = ŝ·√κ, κ = v|s|² / (σ² + v|s|²); a = 0 without smear (or for a feature behind
    the camera, which is never a match)."""
    s2 = np.einsum("ij,ij->i", smear, smear)
    grown = variance * np.where(np.isfinite(s2), s2, 0.0)
    kappa = grown / (np.exp2(2.0 * np.asarray(level, dtype=np.float64)) + grown)
    scale = np.divide(np.sqrt(kappa), np.sqrt(s2), out=np.zeros_like(s2), where=grown > 0.0)
    return np.ascontiguousarray(np.where(np.isfinite(smear), smear, 0.0) * scale[:, None])


def searchable(blur: np.ndarray, level: np.ndarray, patch_size: int, max_widths: float) -> np.ndarray:
    """Patches whose expected blur at their search ``level`` is at most ``max_widths`` patch widths."""
    return blur <= max_widths * patch_size * np.exp2(level)


def unless_blurred(m: PatchMatches, extra: np.ndarray, cfg) -> PatchMatches:
    """The refinement of the ``extra`` patches (below PTAM's sub-pixel levels) where most of them converged;
    where more than ``fine_subpix_blur_fraction`` of their matches did not, the frame is blurred although the
    motion prior was not rapid (the first frame of a sweep), and it keeps PTAM's integer matches for all of them
    instead of losing those matches and, with them, its quality."""
    failed = m.unconverged & extra
    if failed.sum() <= cfg.fine_subpix_blur_fraction * (failed | (m.found & extra)).sum():
        return m
    return dataclasses.replace(m, found=m.found | failed)
