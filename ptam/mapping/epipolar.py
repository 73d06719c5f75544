"""New map points by epipolar search between a new keyframe and its closest keyframe (PTAM §6.2).

PTAM code (``MapMaker::AddPointEpipolar``): a candidate's viewing ray from the source keyframe is cut to
the depth prior (in z) [max(w, mean − σ), min(40·w, mean + σ)] of the source keyframe's scene depth (w is the
stereo-initialisation baseline), projected into the target keyframe's unit plane, and searched there
among FAST corners of the same pyramid level within (4 + 2^level) pixels of the line, by zero-mean SSD
against the unwarped 8×8 source patch. The winner is refined by inverse-compositional sub-pixel search
and triangulated.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..geometry import se3
from ..geometry.triangulation import triangulate_two_view
from ..image.pyramid import level_to_zero, zero_to_level
from ..patch.subpix_kernels import refine_subpix
from ..patch.warp import unwarped_templates
from .epipolar_kernels import epipolar_search

if TYPE_CHECKING:
    from ..camera.model import CameraModel
    from ..config import Config, MapperConfig
    from ..image.pyramid import Pyramid


@dataclass(frozen=True)
class EpipolarMatches:
    X: np.ndarray  # (n, 3) world points
    src_xy: np.ndarray  # (n, 2) level-0 pixels in the source keyframe (the patch centre)
    src_level_xy: np.ndarray  # (n, 2) pixels at the source level
    tgt_xy: np.ndarray  # (n, 2) level-0 pixels in the target keyframe (sub-pixel)
    candidate: np.ndarray  # (n,) index of each match among the candidates searched


@dataclass(frozen=True)
class _Segments:
    """One search segment per candidate on the target keyframe's unit plane: the points x with normal·x = dist
    and along·x in [lo, hi]."""

    normal: np.ndarray  # (n, 2) unit normal of the epipolar line
    dist: np.ndarray  # (n,) signed distance of the line from the optical axis
    along: np.ndarray  # (n, 2) unit direction of the line
    lo: np.ndarray  # (n,)
    hi: np.ndarray  # (n,)

    def take(self, idx: np.ndarray) -> _Segments:
        return _Segments(self.normal[idx], self.dist[idx], self.along[idx], self.lo[idx], self.hi[idx])


def one_pixel_dist(camera: CameraModel) -> float:
    """Unit-plane length of one pixel at the principal point (PTAM code: ``OnePixelDist``)."""
    c = np.array([[camera.cx, camera.cy], [camera.cx + 1.0, camera.cy]])
    xy = camera.unproject(c)
    return float(np.linalg.norm(xy[1] - xy[0]))


def unit_plane_corners(camera: CameraModel, pyramid: Pyramid, level: int) -> np.ndarray:
    """The level's FAST corners on the unit plane (PTAM code caches these per keyframe level)."""
    return camera.unproject(level_to_zero(pyramid.corners[level].astype(np.float64), level))


def _segment_ends(
    camera: CameraModel,
    T_src: np.ndarray,
    T_tgt: np.ndarray,
    root: np.ndarray,
    depth_mean: float,
    depth_sigma: float,
    wiggle: float,
    m: MapperConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The near and far ends (n, 2) on the target keyframe's unit plane of the source rays through ``root``
    (level-0 pixels) cut to the depth prior, and whether the far end is in front of the target camera and
    farther than the near one."""
    # Rays scaled to z = 1 in the source camera: the depth prior is over z (the keyframe's depth statistics
    # are of z), so it is applied along the ray in z, not in range; with a wide-angle lens the two differ by
    # 1/cos of the off-axis angle (PTAM's code uses unit-length rays).
    ray_s = np.concatenate([camera.unproject(root), np.ones((len(root), 1))], axis=1)
    T_ts = T_tgt @ se3.inv(T_src)
    dirn = ray_s @ T_ts[:3, :3].T
    centre = T_ts[:3, 3]
    start = max(wiggle, depth_mean - depth_sigma)
    end = min(m.epipolar_far_depth_mult * wiggle, depth_mean + depth_sigma)
    a3 = centre + start * dirn
    b3 = centre + end * dirn
    ok = (b3[:, 2] > a3[:, 2]) & (b3[:, 2] > 0.0)
    # A near end behind the target camera is pulled forward to just in front of it (PTAM code).
    behind = ok & (a3[:, 2] <= 0.0)
    a3[behind] += dirn[behind] * (m.epipolar_min_z - a3[behind, 2:3]) / dirn[behind, 2:3]
    with np.errstate(divide="ignore", invalid="ignore"):
        a = a3[:, :2] / a3[:, 2:3]
        b = b3[:, :2] / b3[:, 2:3]
    return a, b, ok


def _segments(
    a: np.ndarray, b: np.ndarray, ok: np.ndarray, max_radius: float, m: MapperConfig
) -> tuple[np.ndarray, _Segments]:
    """The segments from ``a`` to ``b`` lengthened by the along-margin, and ``ok`` narrowed to those long enough
    whose line passes within the lens's reach."""
    along = a - b
    alen = np.linalg.norm(along, axis=1)
    ok &= np.isfinite(alen) & (alen > m.epipolar_min_line_length)
    along = along / np.where(alen > 0, alen, 1.0)[:, None]
    normal = np.stack([along[:, 1], -along[:, 0]], axis=1)
    dist = (a * normal).sum(axis=1)
    ok &= np.abs(dist) <= max_radius
    ta, tb = (along * a).sum(axis=1), (along * b).sum(axis=1)
    clip = m.epipolar_along_clip
    lo = np.clip(np.minimum(ta, tb) - m.epipolar_along_margin, -clip, clip)
    hi = np.clip(np.maximum(ta, tb) + m.epipolar_along_margin, -clip, clip)
    return ok, _Segments(normal, dist, along, lo, hi)


def _search_boxes(camera: CameraModel, seg: _Segments, level: int, band_px: float, samples: int) -> np.ndarray:
    """Pixel boxes (n, 4) (x0, y0, x1, y1) at ``level`` that hold each search segment's band: the segment is
    sampled on the unit plane, projected through the lens, and the box padded by the band plus the bulge the
    lens can give the curve between two samples (bounded by the sample spacing)."""
    lo, hi = seg.lo, seg.hi
    t = np.linspace(0.0, 1.0, samples)
    ts = lo[:, None] + (hi - lo)[:, None] * t[None, :]
    pts = seg.along[:, None, :] * ts[..., None] + (seg.normal * seg.dist[:, None])[:, None, :]
    uv = camera.project(np.concatenate([pts, np.ones(pts.shape[:2] + (1,))], axis=-1).reshape(-1, 3))
    uv = zero_to_level(uv, level).reshape(len(lo), samples, 2)
    step = np.linalg.norm(np.diff(uv, axis=1), axis=2).max(axis=1) if samples > 1 else np.zeros(len(lo))
    pad = (band_px / (1 << level) + 1.0 + 0.5 * step)[:, None]
    lo_xy = np.floor(np.nanmin(uv, axis=1) - pad)
    hi_xy = np.ceil(np.nanmax(uv, axis=1) + pad)
    big = np.iinfo(np.int32).max // 2
    box = np.concatenate([np.clip(lo_xy, -big, big), np.clip(hi_xy, -big, big)], axis=1)
    return np.nan_to_num(box, nan=0.0).astype(np.int64)


def _search_target(
    camera: CameraModel,
    tgt_pyr: Pyramid,
    level: int,
    tgt_plane_corners: np.ndarray,
    seg: _Segments,
    templates: np.ndarray,
    cfg: Config,
) -> np.ndarray:
    """Per template, the target corner of the same level that matches it best within the band around its
    segment (index into the level's corners, −1 for none)."""
    m, p = cfg.mapper, cfg.patch
    band_px = m.epipolar_band_px + (1 << level)
    max_perp = np.full(len(templates), one_pixel_dist(camera) * band_px)
    max_ssd = p.max_ssd_per_pixel * p.size * p.size
    box = _search_boxes(camera, seg, level, band_px, m.epipolar_box_samples)
    best, _ = epipolar_search(
        tgt_pyr.levels[level],
        tgt_pyr.corners[level],
        tgt_plane_corners,
        tgt_pyr.row_lut[level],
        box,
        templates,
        seg.normal,
        seg.dist,
        seg.along,
        seg.lo,
        seg.hi,
        max_perp,
        max_ssd,
    )
    return best


def _triangulated(
    camera: CameraModel,
    T_src: np.ndarray,
    T_tgt: np.ndarray,
    src_xy: np.ndarray,
    src_level_xy: np.ndarray,
    tgt_xy: np.ndarray,
    candidate: np.ndarray,
) -> EpipolarMatches:
    """The matches triangulated, keeping those in front of both keyframes."""
    X = triangulate_two_view(T_src, T_tgt, camera.unproject(src_xy), camera.unproject(tgt_xy))
    zs = X @ T_src[2, :3] + T_src[2, 3]
    zt = X @ T_tgt[2, :3] + T_tgt[2, 3]
    good = np.isfinite(X).all(axis=1) & (zs > 0) & (zt > 0)
    return EpipolarMatches(X[good], src_xy[good], src_level_xy[good], tgt_xy[good], candidate[good])


def epipolar_matches(
    camera: CameraModel,
    T_src: np.ndarray,
    T_tgt: np.ndarray,
    src_pyr: Pyramid,
    tgt_pyr: Pyramid,
    depth_mean: float,
    depth_sigma: float,
    level: int,
    cand_xy: np.ndarray,
    tgt_plane_corners: np.ndarray,
    cfg: Config,
) -> EpipolarMatches:
    """Search every candidate (level pixels (n, 2) int in the source keyframe) in the target keyframe."""
    p = cfg.patch
    empty = EpipolarMatches(np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, int))
    if len(cand_xy) == 0 or len(tgt_pyr.corners[level]) == 0:
        return empty
    cand_xy = np.asarray(cand_xy, np.float64)
    root = level_to_zero(cand_xy, level)
    a, b, ok = _segment_ends(camera, T_src, T_tgt, root, depth_mean, depth_sigma, cfg.init.baseline_m, cfg.mapper)
    ok, seg = _segments(a, b, ok, camera.max_radius, cfg.mapper)
    idx = np.flatnonzero(ok)
    if len(idx) == 0:
        return empty
    templates, tok = unwarped_templates(src_pyr, level, cand_xy[idx], p.size)
    idx, templates = idx[tok], templates[tok]
    if len(idx) == 0:
        return empty
    best = _search_target(camera, tgt_pyr, level, tgt_plane_corners, seg.take(idx), templates, cfg)
    found = best >= 0
    idx, templates, best = idx[found], templates[found], best[found]
    if len(idx) == 0:
        return empty
    start_xy = tgt_pyr.corners[level][best].astype(np.float64)
    refined, conv = refine_subpix(
        tgt_pyr.levels,
        templates,
        np.full(len(idx), level, np.int8),
        start_xy,
        p.subpix_iterations,
        p.subpix_converge_px,
    )
    idx = idx[conv]
    return _triangulated(camera, T_src, T_tgt, root[idx], cand_xy[idx], level_to_zero(refined[conv], level), idx)
