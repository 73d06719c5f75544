"""The small blurry image (Agility §6, §7; PTAM code ``SmallBlurryImage``).

The coarsest pyramid level (80×60 for 640×480) is half-sampled once more (40×30), blurred with a Gaussian of
σ small-image pixels and made zero-mean. The rotation estimator uses σ = 0.75 (§6), the relocaliser σ = 2.5
(§7). Its central-difference gradient is the template half of the ESM Jacobian, and SE(2) alignments of one
image to another are found by :func:`ptam.image.esm_kernels.esm_se2`.

Small-image pixel x sits at level-0 pixel (x + 0.5)·2^L − 0.5 with L = the pyramid's levels (one octave above
the coarsest level), as for every pyramid level.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .esm_kernels import esm_se2
from .pyramid import Pyramid, half_sample


def small_image(pyramid: Pyramid) -> np.ndarray:
    """The coarsest pyramid level half-sampled once more (uint8, 40×30 for 640×480)."""
    return half_sample(pyramid.levels[-1])


def small_level(pyramid: Pyramid) -> int:
    """The pyramid level of the small image (one octave above the coarsest level)."""
    return pyramid.n_levels


def gradient(image: np.ndarray) -> np.ndarray:
    """Central differences (H, W, 2) float32, zero on the border (PTAM code ``MakeJacs``, halved)."""
    g = np.zeros((*image.shape, 2), np.float32)
    g[1:-1, 1:-1, 0] = 0.5 * (image[1:-1, 2:] - image[1:-1, :-2])
    g[1:-1, 1:-1, 1] = 0.5 * (image[2:, 1:-1] - image[:-2, 1:-1])
    return g


@dataclass(frozen=True)
class Alignment:
    """An SE(2) (+ offset) alignment: template pixel x lies at c + R(θ)(x − c) + t in the aligned image."""

    params: np.ndarray  # (t_x, t_y, θ, intensity offset)
    score: float  # SSD over the pixels used in the last iteration
    iterations: int


@dataclass(frozen=True)
class SmallBlurryImage:
    """``image``: zero-mean blurred small image (H, W) float32; ``grad``: its derivative (H, W, 2)."""

    image: np.ndarray
    grad: np.ndarray

    @classmethod
    def from_small(cls, small: np.ndarray, sigma: float) -> SmallBlurryImage:
        """Agility §7 order: blur, then subtract the mean."""
        img = cv2.GaussianBlur(np.asarray(small, np.float32), (0, 0), float(sigma), borderType=cv2.BORDER_REFLECT)
        img -= img.mean(dtype=np.float32)
        return cls(img, gradient(img))

    @classmethod
    def from_pyramid(cls, pyramid: Pyramid, sigma: float) -> SmallBlurryImage:
        return cls.from_small(small_image(pyramid), sigma)

    def align_to(
        self,
        template: SmallBlurryImage,
        iterations: int,
        with_offset: bool,
        start: np.ndarray | None = None,
        robust: bool = False,
    ) -> Alignment:
        """ESM over SE(2) (and an intensity offset) of this image onto ``template`` (Agility §6, §7); ``robust``:
        Tukey-weighted (``esm_se2``)."""
        p0 = np.zeros(4) if start is None else np.asarray(start, np.float64)
        args = (p0, int(iterations), bool(with_offset), bool(robust))
        p, score, its = esm_se2(self.image, template.image, template.grad, *args)
        return Alignment(p, float(score), int(its))

    def ssd(self, other: SmallBlurryImage) -> float:
        """Zero-mean SSD (both images are zero-mean already; PTAM code ``ZMSSD``)."""
        d = self.image - other.image
        return float(np.vdot(d, d))
