"""2-D patch trails followed from the first keyframe during stereo initialisation (PTAM §6.1).

PTAM code (``Tracker::TrailTracking_Start/Advance``): up to 1000 maximal FAST corners of level 0 with
the best Shi-Tomasi scores start trails. Each frame, a trail's patch from the first keyframe is searched
at FAST corners around the trail's last position; a backward search of the found patch in the previous
frame must land within √2 px of where the trail was, or the trail is dropped.

ptam: the searches compensate a frame-wide change of brightness (auto exposure, lighting; PTAM's plain SSD
drops nearly every trail when the image brightens by 10 %): the gain of a frame against the first keyframe is
the median ratio of the trails' patch means, measured on the previous frame for the forward search and on the
matches found for the backward one. ``init.trail_global_gain: false`` is PTAM's plain SSD.

ptam: PTAM searches each trail around its last position, so trails survive only image motion within the search
radius (10 px) per frame; at 10 fps, or under a hand's shake, all die within a frame or two and initialisation
never starts. Where a rotation between the two frames is known (the panorama tracked from the first frame,
Gauglitz §4.3; Agility §6's motion prior), the forward search is centred where that rotation moves the trail, and
the backward search where the inverse of the same shift puts the match: with no rotation both are PTAM's.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..camera.model import CameraModel
from ..image.fast import fast_corners
from ..image.pyramid import Pyramid
from ..image.shi_tomasi import shi_tomasi
from .minipatch_kernels import minipatch_find


class TrailTracker:
    def __init__(self, init_cfg, image_cfg):
        self.cfg = init_cfg
        self.image_cfg = image_cfg
        self.first: Pyramid | None = None
        self.previous: Pyramid | None = None
        self.start_xy = np.zeros((0, 2), np.int32)
        self.current_xy = np.zeros((0, 2), np.int32)
        self.ids = np.zeros(0, np.int64)  # each live trail's index among those started, to follow it across frames
        self.frames = 0
        self.first_sums = np.zeros(0)  # each live trail's patch sum in the first keyframe, for the gain
        self.gain = 1.0  # brightness of the previous frame relative to the first keyframe

    @property
    def n_trails(self) -> int:
        return len(self.start_xy)

    def start(self, pyramid: Pyramid) -> int:
        img = pyramid.levels[0]
        xy = fast_corners(img, self.image_cfg.fast_thresholds[0], nonmax=True)
        h = self.cfg.trail_half_patch
        H, W = img.shape
        xy = xy[(xy[:, 0] >= h) & (xy[:, 1] >= h) & (xy[:, 0] < W - h) & (xy[:, 1] < H - h)]
        score = shi_tomasi(img, xy, self.image_cfg.shi_tomasi_half_box)
        order = np.argsort(-score, kind="stable")[: self.cfg.max_trails]
        self.start_xy = np.ascontiguousarray(xy[order], dtype=np.int32)
        self.current_xy = self.start_xy.copy()
        self.ids = np.arange(self.n_trails)
        self.first = self.previous = pyramid
        self.frames = 0
        self.first_sums = patch_sums(cv2.integral(img), self.start_xy, h)
        self.gain = 1.0
        return self.n_trails

    def _gain(self, sums: np.ndarray, xy: np.ndarray, found: np.ndarray) -> float:
        """Median over the ``found`` trails of (patch mean at ``xy`` in the frame of ``sums``) / (its mean in the
        first keyframe)."""
        if not found.any():
            return self.gain
        num = patch_sums(sums, xy[found], self.cfg.trail_half_patch)
        den = self.first_sums[found]
        valid = den > 0
        return float(np.median(num[valid] / den[valid])) if valid.any() else self.gain

    def advance(self, pyramid: Pyramid, predicted: np.ndarray | None = None) -> int:
        """Follow every trail into ``pyramid``, searched around ``predicted`` (T, 2) int32 pixels (default: where
        each trail was); drops the trails that fail. Returns the number kept."""
        if self.first is None or self.previous is None or self.n_trails == 0:
            return 0
        c = self.cfg
        centre = self.current_xy if predicted is None else predicted
        sums = cv2.integral(pyramid.levels[0]) if c.trail_global_gain else None
        fwd, ok = minipatch_find(
            self.first.levels[0],
            self.start_xy,
            pyramid.levels[0],
            centre,
            pyramid.corners[0],
            pyramid.row_lut[0],
            c.trail_search_radius_px,
            c.trail_half_patch,
            c.trail_max_ssd,
            self.gain,
        )
        gain = self._gain(sums, fwd, ok) if sums is not None else 1.0
        back, ok_b = minipatch_find(
            pyramid.levels[0],
            fwd,
            self.previous.levels[0],
            fwd + (self.current_xy - centre),  # where the match came from, by the predicted shift
            self.previous.corners[0],
            self.previous.row_lut[0],
            c.trail_search_radius_px,
            c.trail_half_patch,
            c.trail_max_ssd,
            self.gain / gain,
        )
        d2 = ((back - self.current_xy) ** 2).sum(axis=1)
        keep = ok & ok_b & (d2 <= c.trail_backward_tolerance_px2)
        self.start_xy = self.start_xy[keep]
        self.first_sums = self.first_sums[keep]
        self.current_xy = fwd[keep]
        self.ids = self.ids[keep]
        self.previous = pyramid
        self.gain = gain
        self.frames += 1
        return self.n_trails

    def rotated(self, camera: CameraModel, R: np.ndarray) -> np.ndarray:
        """Where the rotation ``R`` (previous frame's camera to the next's) moves each trail's last position, as
        int32 pixels, clamped to within a search radius of the image (a trail whose ray turns behind the camera
        stays where it was)."""
        xy = self.current_xy
        rays = camera.unproject_rays(xy.astype(np.float64)) @ R.T
        ahead = rays[:, 2] > 0.0
        uv = xy.astype(np.float64)
        uv[ahead] = camera.project(rays[ahead])
        lost = ~np.isfinite(uv).all(axis=1)
        uv[lost] = xy[lost]
        r = self.cfg.trail_search_radius_px
        uv = np.clip(uv, -r - 1, [camera.width + r, camera.height + r])
        return np.rint(uv).astype(np.int32)

    def median_disparity(self) -> float:
        if self.n_trails == 0:
            return 0.0
        return float(np.median(np.linalg.norm((self.current_xy - self.start_xy).astype(np.float64), axis=1)))


def patch_sums(sums: np.ndarray, xy: np.ndarray, half: int) -> np.ndarray:
    """Grey-level sums of the (2·half+1)² patches centred at integer ``xy``, from an integral image."""
    x0 = xy[:, 0] - half
    y0 = xy[:, 1] - half
    x1 = xy[:, 0] + half + 1
    y1 = xy[:, 1] + half + 1
    return (sums[y1, x1] - sums[y0, x1] - sums[y1, x0] + sums[y0, x0]).astype(np.float64)
