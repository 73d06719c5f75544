"""The renderer: per-sample rays through the camera model (distortion included) and the ray-cast kernel.

Rays and their per-pixel differentials depend only on the camera, so they are computed once with
``camera.unproject_rays``; each frame then costs one call of ``ptam.synthetic.render_kernels.render``, which
releases the GIL so frames render in parallel threads.
"""

from __future__ import annotations

import functools
import json

import numpy as np

from ..camera import CameraModel
from .mipmap import TextureAtlas
from .rectangle import Rectangle
from .render_kernels import render, tile_cones
from .texture import make_texture

_DIFF_STEP_PX = 0.5  # half-width of the central difference giving ∂ray/∂(u, v)
_TEXTURE_MEMO = 8  # textures kept in memory across Scene objects (tests load the same scene repeatedly)


@functools.lru_cache(maxsize=_TEXTURE_MEMO)
def _texture(spec_json: str, width_m: float, height_m: float, where: str):
    tex, texel = make_texture(json.loads(spec_json), width_m, height_m, where)
    tex.setflags(write=False)
    return tex, texel


def sample_offsets(n: int) -> np.ndarray:
    """(n², 2) sample offsets inside a pixel (centre at 0): an n×n grid turned by atan(1/n) (rotated-grid
    supersampling). Its n² samples have n² distinct x and n² distinct y offsets, so a near-vertical or
    near-horizontal edge is placed to 1/n² px, where an axis-aligned grid gives only 1/n."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    ix, iy = i * n - j + (n - 1), i + j * n
    return np.stack([ix.ravel(), iy.ravel()], axis=-1) / (n * n) + (0.5 / (n * n) - 0.5)


class Renderer:
    def __init__(self, camera: CameraModel, rectangles: list[Rectangle], supersample: int, background: float):
        self.camera = camera
        self.background = float(background)
        self.sample_step = 1.0 / supersample
        textures = [
            _texture(json.dumps(r.texture, sort_keys=True), r.size[0], r.size[1], f"rectangle '{r.name}'")
            for r in rectangles
        ]
        self.atlas = TextureAtlas(textures)
        self.rects = np.ascontiguousarray(np.stack([r.packed() for r in rectangles]))
        self.rect_tex = np.arange(len(rectangles), dtype=np.int64)
        W, H = camera.width, camera.height
        uu, vv = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64), indexing="xy")
        pix = np.stack([uu, vv], axis=-1).reshape(-1, 1, 2)
        offs = sample_offsets(supersample)
        self.rays = camera.unproject_rays((pix + offs[None]).reshape(-1, 2)).reshape(H, W, len(offs), 3)
        h = _DIFF_STEP_PX
        pix = pix.reshape(-1, 2)
        self.crays = camera.unproject_rays(pix).reshape(H, W, 3)
        drays = []
        for step in (np.array([h, 0.0]), np.array([0.0, h])):
            drays.append((camera.unproject_rays(pix + step) - camera.unproject_rays(pix - step)) / (2.0 * h))
        self.drays = np.ascontiguousarray(np.stack(drays, axis=1).reshape(H, W, 2, 3))
        self.tile_axis, self.tile_sin = tile_cones(self.rays)

    def kernel_args(self, poses_T_wc: np.ndarray) -> tuple:
        a = self.atlas
        return (
            self.rays,
            self.crays,
            self.drays,
            self.sample_step,
            np.ascontiguousarray(poses_T_wc, dtype=np.float64),
            self.rects,
            self.rect_tex,
            a.data,
            a.info,
            a.n_levels,
            a.texel,
            self.background,
            self.tile_axis,
            self.tile_sin,
        )

    def render(self, poses_T_wc: np.ndarray) -> np.ndarray:
        """Mean shade (H, W) float32 over the sub-frame poses (P, 4, 4)."""
        out = np.empty((self.camera.height, self.camera.width), dtype=np.float32)
        render(*self.kernel_args(poses_T_wc), out)
        return out
