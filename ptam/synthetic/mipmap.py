"""Mip-map pyramids of all textures packed into one flat array for the render kernel.

Level l+1 averages 2×2 texels of level l (odd sizes are padded by repeating the last row/column), so a
level-l texel is exactly 2^l level-0 texels wide and the texture coordinates scale by 2^-l.
"""

from __future__ import annotations

import numpy as np


def mip_levels(tex: np.ndarray) -> list[np.ndarray]:
    levels = [np.ascontiguousarray(tex, dtype=np.float32)]
    while max(levels[-1].shape) > 1:
        t = levels[-1]
        t = np.pad(t, ((0, t.shape[0] % 2), (0, t.shape[1] % 2)), mode="edge")
        levels.append(0.25 * (t[0::2, 0::2] + t[1::2, 0::2] + t[0::2, 1::2] + t[1::2, 1::2]))
    return levels


class TextureAtlas:
    """``data`` (flat float32), ``info[t, l] = (offset, width, height)``, ``n_levels[t]``, ``texel[t]`` (m)."""

    def __init__(self, textures: list[tuple[np.ndarray, float]]):
        pyramids = [mip_levels(t) for t, _ in textures]
        max_levels = max(len(p) for p in pyramids)
        self.info = np.zeros((len(pyramids), max_levels, 3), dtype=np.int64)
        self.n_levels = np.array([len(p) for p in pyramids], dtype=np.int64)
        self.texel = np.array([s for _, s in textures], dtype=np.float64)
        chunks, offset = [], 0
        for t, pyr in enumerate(pyramids):
            for lev, img in enumerate(pyr):
                self.info[t, lev] = (offset, img.shape[1], img.shape[0])
                chunks.append(img.ravel())
                offset += img.size
        self.data = np.concatenate(chunks).astype(np.float32)
