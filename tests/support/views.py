"""Synthetic views for tests that need real images without rendering a scene: a corner-rich texture, and the view
of a camera turned in place from where it was taken."""

from __future__ import annotations

import cv2
import numpy as np


def texture(h: int = 480, w: int = 640, seed: int = 0) -> np.ndarray:
    """Blurred noise with strong contrast: a corner-rich image."""
    rng = np.random.default_rng(seed)
    img = cv2.GaussianBlur(rng.integers(0, 256, (h, w)).astype(np.uint8), (0, 0), 3).astype(np.float64)
    return np.clip((img - img.mean()) * 6 + 128, 0, 255).astype(np.uint8)


def turned_view(camera, img: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The view of a camera turned by R (x₁ = R·x₀) from where ``img`` was taken, through the same lens."""
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    rays = camera.unproject_rays(np.stack([u, v], axis=-1).reshape(-1, 2).astype(np.float64)) @ R  # Rᵀ x₁
    uv = camera.project(rays).reshape(camera.height, camera.width, 2).astype(np.float32)
    return cv2.remap(img, uv[..., 0], uv[..., 1], cv2.INTER_LINEAR, borderValue=0)
