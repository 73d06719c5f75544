"""Synthetic images with exactly known edges for the edgelet tests (not part of the ptam package).

``edge_image``: a straight step edge (dark → light along ``normal``) through ``point``, each pixel the mean of
an ss × ss grid of samples over its area, optionally box motion-blurred by ``blur`` px along ``blur_dir``: a
straight edge blurred along u is the same edge blurred along its normal by blur·|n·u| (shifts along the edge
change nothing), so each sample takes the exact blurred value, a linear ramp of that length.

``polygon_image``: filled polygons of given grey levels over a background, area-sampled the same way
(the edges of convex polygons are exactly known for the candidate-extraction test).
"""

from __future__ import annotations

import numpy as np


def _sample_grid(W: int, H: int, ss: int) -> tuple[np.ndarray, np.ndarray]:
    o = (np.arange(ss) + 0.5) / ss - 0.5
    xs = (np.arange(W)[:, None] + o[None, :]).ravel()
    ys = (np.arange(H)[:, None] + o[None, :]).ravel()
    return np.meshgrid(xs, ys, indexing="xy")


def _area_mean(values: np.ndarray, W: int, H: int, ss: int) -> np.ndarray:
    return values.reshape(H, ss, W, ss).mean(axis=(1, 3))


def edge_image(W, H, point, normal, lo, hi, blur=0.0, blur_dir=None, noise=0.0, seed=0, ss=8, quantise=True):
    """A (H, W) image of one straight edge; float32, or uint8 when ``quantise``."""
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    X, Y = _sample_grid(W, H, ss)
    s = (X - point[0]) * n[0] + (Y - point[1]) * n[1]
    u = n if blur_dir is None else np.asarray(blur_dir, dtype=np.float64) / np.linalg.norm(blur_dir)
    ramp = float(blur) * abs(float(n @ u))
    f = (s > 0).astype(np.float64) if ramp <= 1e-9 else np.clip(s / ramp + 0.5, 0.0, 1.0)
    img = lo + (hi - lo) * _area_mean(f, W, H, ss)
    if noise > 0:
        img = img + np.random.default_rng(seed).normal(0.0, noise, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8) if quantise else img.astype(np.float32)


def polygon_image(W, H, polygons, greys, background, noise=0.0, seed=0, ss=4):
    """Convex polygons (list of (K, 2) vertex arrays, counter-clockwise or clockwise) painted in order."""
    X, Y = _sample_grid(W, H, ss)
    val = np.full(X.shape, float(background))
    for P, g in zip(polygons, greys):
        P = np.asarray(P, dtype=np.float64)
        area2 = np.sum(P[:, 0] * np.roll(P[:, 1], -1) - np.roll(P[:, 0], -1) * P[:, 1])
        sign = 1.0 if area2 > 0 else -1.0
        inside = np.ones(X.shape, dtype=bool)
        for k in range(len(P)):
            a, b = P[k], P[(k + 1) % len(P)]
            cross = (b[0] - a[0]) * (Y - a[1]) - (b[1] - a[1]) * (X - a[0])
            inside &= sign * cross > 0
        val[inside] = g
    img = _area_mean(val, W, H, ss)
    if noise > 0:
        img = img + np.random.default_rng(seed).normal(0.0, noise, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def polygon_edges(polygons, greys, background):
    """The true edges: (E, 2, 2) segment end points with the dark-to-light normal of each (E, 2) (for polygons
    that do not overlap)."""
    segs, normals = [], []
    for P, g in zip(polygons, greys):
        P = np.asarray(P, dtype=np.float64)
        area2 = np.sum(P[:, 0] * np.roll(P[:, 1], -1) - np.roll(P[:, 0], -1) * P[:, 1])
        for k in range(len(P)):
            a, b = P[k], P[(k + 1) % len(P)]
            t = (b - a) / np.linalg.norm(b - a)
            outward = np.array([t[1], -t[0]]) * (1.0 if area2 > 0 else -1.0)
            segs.append(np.stack([a, b]))
            normals.append(-outward if g > background else outward)
    return np.array(segs), np.array(normals)
