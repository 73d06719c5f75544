"""Keyframe-based relocalisation from small blurry images (Agility §7; PTAM code ``Relocaliser``).

Every keyframe's descriptor is its 40×30 small image blurred with σ = ``reloc.blur_sigma`` (2.5) and made
zero-mean. When tracking is lost, the frame's descriptor is compared with every keyframe's by sum of squared
differences; the camera is placed at the best keyframe's pose, rotated by the SE(2) + intensity-offset ESM
alignment of the two small images converted to a 3-D rotation (as in §6), and tracking restarts from there. The
attempt is accepted when the aligned SSD is below ``reloc.max_score`` (PTAM code).

The relocaliser reads only the immutable :class:`~ptam.map.snapshot.MapSnapshot` and never changes the map.
Keyframes are immutable, so their descriptors are computed once, when a snapshot first shows them
(:meth:`Relocaliser.sync`), and stacked so that the comparison is one matrix-vector product.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..geometry import se3
from ..image.pyramid import Pyramid
from ..image.sbi import Alignment, SmallBlurryImage, small_level
from ..vocabulary import Quality
from .rotation_estimator import rotation_from_se2, sample_offsets


@dataclass(frozen=True)
class Relocalisation:
    """An attempt: the best keyframe, its zero-mean SSD to the frame, the alignment and the pose it gives."""

    keyframe: int
    ssd: float
    alignment: Alignment
    T_cw: np.ndarray
    accepted: bool


class Relocaliser:
    def __init__(self, camera, cfg):
        self.camera = camera
        self.cfg = cfg.reloc
        self.offsets = sample_offsets(cfg.rotation.sample_radius_px)
        self._keyframes: list = []  # the KeyFrame objects whose descriptors are stacked
        self._images = np.zeros((0, 0, 0), np.float32)
        self._grads = np.zeros((0, 0, 0, 2), np.float32)
        self._sq_norms = np.zeros(0)

    @property
    def n_keyframes(self) -> int:
        return len(self._keyframes)

    def sync(self, snapshot) -> None:
        """Add the descriptors of keyframes new in ``snapshot``; start over if it is another map."""
        kfs: Sequence = () if snapshot is None else snapshot.keyframes
        n = len(self._keyframes)
        if n and (len(kfs) < n or kfs[0] is not self._keyframes[0] or kfs[n - 1] is not self._keyframes[-1]):
            self._keyframes, n = [], 0
        for kf in kfs[n:]:
            self._append(SmallBlurryImage.from_pyramid(kf.pyramid, self.cfg.blur_sigma))
            self._keyframes.append(kf)

    def _append(self, sbi: SmallBlurryImage) -> None:
        i = len(self._keyframes)
        if i == 0 or i == len(self._images):
            cap = max(2 * i, 8)
            images = np.zeros((cap, *sbi.image.shape), np.float32)
            grads = np.zeros((cap, *sbi.grad.shape), np.float32)
            sq = np.zeros(cap)
            if i:
                images[:i], grads[:i], sq[:i] = self._images[:i], self._grads[:i], self._sq_norms[:i]
            self._images, self._grads, self._sq_norms = images, grads, sq
        self._images[i] = sbi.image
        self._grads[i] = sbi.grad
        self._sq_norms[i] = float(np.vdot(sbi.image, sbi.image))

    def descriptor_ssd(self, frame: SmallBlurryImage) -> np.ndarray:
        """Zero-mean SSD of ``frame`` to every keyframe's descriptor (K,): |k|² + |f|² − 2 k·f."""
        n = len(self._keyframes)
        f = frame.image.ravel()
        return self._sq_norms[:n] + float(np.vdot(f, f)) - 2.0 * (self._images[:n].reshape(n, -1) @ f)

    def attempt(self, pyramid: Pyramid, snapshot, frame: SmallBlurryImage | None = None) -> Relocalisation | None:
        """One relocalisation attempt for the frame of ``pyramid`` (PTAM code ``AttemptRecovery``); None when
        the map has no keyframes. ``frame``: the frame's descriptor, when already made."""
        c = self.cfg
        self.sync(snapshot)
        if not self._keyframes:
            return None
        if frame is None:
            frame = SmallBlurryImage.from_pyramid(pyramid, c.blur_sigma)
        ssd = self.descriptor_ssd(frame)
        best = int(np.argmin(ssd))
        alignment = frame.align_to(SmallBlurryImage(self._images[best], self._grads[best]), c.iterations, True)
        R = rotation_from_se2(self.camera, alignment.params, frame.image.shape, small_level(pyramid), self.offsets)
        T = se3.from_Rt(R, np.zeros(3)) @ snapshot.kf_T_cw[best]
        accepted = alignment.iterations > 0 and alignment.score < c.max_score
        return Relocalisation(best, float(ssd[best]), alignment, T, bool(accepted))


def confirms(res, cfg) -> bool:
    """Whether a frame tracked from a relocalised pose counts towards confirming it (``cfg``: the ``reloc``
    section): good quality, and most of the patches searched kept as Tukey inliers (texture is found anywhere at
    a wrong pose, but does not fit it). ``confirm_frames`` such frames in a row confirm a relocalisation."""
    return res.quality == Quality.GOOD and res.inlier_fraction > cfg.confirm_inlier_fraction
