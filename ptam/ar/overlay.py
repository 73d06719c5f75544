"""Draws a ``DrawList`` onto a camera frame through the real camera model, distortion included (PTAM §7.5).

PTAM renders with OpenGL into an undistorted frame buffer and warps it with a coarse mesh; here nothing is
undistorted: the grid's dense samples are projected with the lens model and drawn as anti-aliased polylines at
sub-pixel positions,
spheres and plane decals are ray-cast per pixel along the exact unprojected ray of each pixel
(``ptam.ar.raster_kernels``), with a z-buffer among the spheres. Order: frame, grid, spheres, decals (shadows,
rings; only where no sphere was drawn: a sphere resting on the plane is always nearer a camera above the plane
than the plane behind it), then the screen cross-hair and text.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from ..camera.camproj_kernels import project_points
from . import materials
from .drawlist import DrawList
from .grid import make_grid, project_grid
from .raster_kernels import (
    D_ROUT,
    D_SOFT,
    S_RADIUS,
    S_ROT,
    blend_coverage,
    draw_decals,
    draw_spheres,
    outline_boxes,
    rasterise_polylines,
    ray_table,
)

FIXED_POINT_SHIFT = 4  # cv2 drawing of the screen cross-hair: coordinates in 1/16 px

_VALID_RADIUS_FACTOR = 1.5  # as camproj_kernels.project: the projectable cone is 1.5x the image's largest radius


def camera_ray_table(camera) -> np.ndarray:
    """The rasteriser's per-pixel ray table (``ptam.ar.raster_kernels.ray_table``) from the exact unprojection."""
    W, H = camera.size
    u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    return ray_table(camera.unproject(np.stack([u, v], axis=-1).reshape(-1, 2)).reshape(H, W, 2))


def _grey(colour) -> bool:
    return colour[0] == colour[1] == colour[2]


def grey_overlay(dl: DrawList) -> bool:
    """Whether ``dl`` draws only grey (B = G = R) over a grey frame: the grid (white) and nothing else."""
    return not (len(dl.spheres) or len(dl.decals) or dl.crosshair or dl.text) and _grey(materials.GRID)


def _orthonormal_to(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (N, 3) spanning the plane perpendicular to unit vectors d (N, 3)."""
    a = np.where(np.abs(d[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    e1 = np.cross(d, a)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(d, e1)


class OverlayRenderer:
    def __init__(self, camera, ar_cfg):
        self.camera = camera
        self.cfg = ar_cfg
        self.cam_params = camera.kernel_params()
        self.width, self.height = camera.size
        self.rays = camera_ray_table(camera)
        self.zbuf = np.full((self.height, self.width), np.inf)  # kept empty between frames
        self.coverage = np.zeros((self.height, self.width), np.float32)  # kept zero between frames
        self.touched = np.empty(self.width * self.height + 1, np.int64)  # + rasterise_polylines' scratch slot
        self.grid = make_grid(ar_cfg.grid_half_cells, ar_cfg.grid_spacing, ar_cfg.grid_samples_per_cell)
        self.last_grid = None  # the ProjectedGrid of the latest frame (its exact vertex positions)
        light = np.asarray(ar_cfg.light_direction, np.float64)
        self.light_plane = light / np.linalg.norm(light)
        self.shading = np.array([ar_cfg.ambient, ar_cfg.diffuse, ar_cfg.specular, ar_cfg.shininess])
        # The projectable cone (a hair inside, so points pulled onto its edge still project as valid).
        self.max_radius = _VALID_RADIUS_FACTOR * camera.max_radius * (1.0 - 1e-9)
        self.max_angle = math.atan(self.max_radius)
        phi = np.linspace(0.0, 2.0 * np.pi, materials.SILHOUETTE_SAMPLES, endpoint=False)
        self._circle = np.stack([np.cos(phi), np.sin(phi)], axis=1)

    # -- per frame -------------------------------------------------------------------------------------------
    def render(self, image: np.ndarray, T_cp: np.ndarray, dl: DrawList, grey_ok: bool = False) -> np.ndarray:
        """The frame (grey (H, W) or BGR (H, W, 3) uint8) with the overlay, as a new BGR uint8 image.

        ``grey_ok``: a grey frame whose overlay is grey too (:func:`grey_overlay`: the white grid alone) is drawn
        in its one channel and returned grey (H, W): the same pixels as each channel of the BGR image, at a third
        of the blending and, for a JPEG, about two thirds of the encoding. The grid, drawn first, always goes into
        a grey frame's one channel; the frame becomes BGR after it, for what is coloured."""
        grey = image.ndim == 2 and _grey(materials.GRID)
        img = image.copy() if grey or image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        self.last_grid = None
        if dl.grid_alpha > 0.0:
            self._draw_grid(img[..., None] if img.ndim == 2 else img, T_cp, min(dl.grid_alpha, 1.0))
        if img.ndim == 2 and not (grey_ok and grey_overlay(dl)):
            img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
        R, t = T_cp[:3, :3], T_cp[:3, 3]
        boxes = self._draw_spheres(img, R, t, dl.spheres) if len(dl.spheres) else None
        try:
            if len(dl.decals):
                self._draw_decals(img, R, t, dl.decals)
        finally:
            for x0, y0, x1, y1 in () if boxes is None else boxes:  # the z-buffer is empty between frames
                self.zbuf[y0:y1, x0:x1] = np.inf
        self._draw_hud(img, dl)
        return img

    def _draw_grid(self, img, T_cp, alpha: float) -> None:
        pg = project_grid(self.grid, self.cam_params, T_cp)
        self.last_grid = pg
        n = rasterise_polylines(self.coverage, self.touched, pg.uv, pg.ok, 0.5 * self.cfg.grid_line_px)
        blend_coverage(img, self.coverage, self.touched, n, np.asarray(materials.GRID, np.float64), alpha)

    def _boxes(self, samples: np.ndarray, visible: np.ndarray) -> np.ndarray:
        """Pixel boxes (N, 4) of projected outline samples (N, K, 3) (``raster_kernels.outline_boxes``)."""
        return outline_boxes(
            np.ascontiguousarray(samples),
            visible,
            self.cam_params,
            self.max_radius,
            self.width,
            self.height,
            materials.BOX_MARGIN_PX,
        )

    def _draw_spheres(self, img, R, t, rec_p: np.ndarray) -> np.ndarray:
        """Draw the spheres (plane-frame records) and return the pixel boxes whose z-buffer they wrote."""
        rec = rec_p.copy()
        c = rec_p[:, 0:3] @ R.T + t
        rec[:, 0:3] = c
        rec[:, S_ROT : S_ROT + 9] = (R @ rec_p[:, S_ROT : S_ROT + 9].reshape(-1, 3, 3)).reshape(-1, 9)
        r = rec[:, S_RADIUS]
        dist = np.linalg.norm(c, axis=1)
        outside = dist > r
        with np.errstate(invalid="ignore", divide="ignore"):
            off_axis = np.arctan2(np.hypot(c[:, 0], c[:, 1]), c[:, 2])
            half_angle = np.arcsin(np.clip(r / dist, 0.0, 1.0))
            dirs = c / dist[:, None]
            shrink = 1.0 - (r / dist) ** 2
        visible = outside & (off_axis - half_angle < self.max_angle)
        if not visible.any():
            return np.zeros((0, 4), np.int64)
        # The silhouette is the circle where the tangent cone from the camera touches the sphere.
        e1, e2 = _orthonormal_to(np.where(visible[:, None], dirs, [[0.0, 0.0, 1.0]]))
        centre = c * np.where(visible, shrink, 0.0)[:, None]
        rho = r * np.sqrt(np.clip(shrink, 0.0, 1.0))
        outline = centre[:, None] + rho[:, None, None] * (
            self._circle[None, :, :1] * e1[:, None] + self._circle[None, :, 1:] * e2[:, None]
        )
        boxes = self._boxes(outline, visible)
        order = np.argsort(-np.where(visible, dist, -np.inf))  # back to front: rims blend over what is behind
        order = order[visible[order]]
        boxes = np.ascontiguousarray(boxes[order])
        draw_spheres(
            img, self.zbuf, self.rays, np.ascontiguousarray(rec[order]), boxes, R @ self.light_plane, self.shading
        )
        return boxes

    def _draw_decals(self, img, R, t, dec: np.ndarray) -> None:
        plane = np.concatenate([t, R[:, 0], R[:, 1], R[:, 2]])
        reach = dec[:, D_ROUT] + dec[:, D_SOFT]
        pts = np.zeros((len(dec), len(self._circle) + 1, 3))
        pts[:, :-1, :2] = dec[:, None, 0:2] + reach[:, None, None] * self._circle[None]
        pts[:, -1, :2] = dec[:, 0:2]
        Xc = pts @ R.T + t
        _, ok = project_points(self.cam_params, np.ascontiguousarray(Xc.reshape(-1, 3)))
        visible = ok.reshape(len(dec), -1).any(axis=1)
        boxes = self._boxes(Xc[:, :-1], visible)
        draw_decals(img, self.zbuf, self.rays, plane, np.ascontiguousarray(dec), boxes)

    def _draw_hud(self, img, dl: DrawList) -> None:
        s = 1 << FIXED_POINT_SHIFT
        cx, cy = self.camera.cx, self.camera.cy
        if dl.crosshair:
            colour = materials.AIM_RING_LOCKED if dl.crosshair_locked else materials.CROSSHAIR
            a, b = materials.CROSSHAIR_ARM_PX
            for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                p = (round((cx + a * dx) * s), round((cy + a * dy) * s))
                q = (round((cx + b * dx) * s), round((cy + b * dy) * s))
                cv2.line(img, p, q, colour, 2, cv2.LINE_AA, FIXED_POINT_SHIFT)
            if dl.dwell > 0.0:
                r = materials.DWELL_ARC_PX * s
                cv2.ellipse(
                    img,
                    (round(cx * s), round(cy * s)),
                    (r, r),
                    -90.0,
                    0.0,
                    360.0 * min(dl.dwell, 1.0),
                    materials.AIM_RING_LOCKED,
                    2,
                    cv2.LINE_AA,
                    FIXED_POINT_SHIFT,
                )
        y = materials.TEXT_MARGIN_PX
        for line in dl.text:
            (w, h), base = cv2.getTextSize(line, cv2.FONT_HERSHEY_SIMPLEX, materials.FONT_SCALE, 1)
            m = materials.TEXT_MARGIN_PX // 2
            box = img[
                max(y - m, 0) : y + h + base + m,
                max(materials.TEXT_MARGIN_PX - m, 0) : materials.TEXT_MARGIN_PX + w + m,
            ]
            box[:] = box // 2  # a darkened panel keeps the text readable on any background
            cv2.putText(
                img,
                line,
                (materials.TEXT_MARGIN_PX, y + h),
                cv2.FONT_HERSHEY_SIMPLEX,
                materials.FONT_SCALE,
                materials.HUD_TEXT,
                1,
                cv2.LINE_AA,
            )
            y += h + base + 2 * m
