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

import numpy as np

from ..geometry import se3
from ..geometry.triangulation import triangulate_two_view
from ..image.pyramid import level_to_zero, zero_to_level
from ..patch.subpix_kernels import refine_subpix
from ..patch.template_kernels import make_templates
from .epipolar_kernels import epipolar_search


@dataclass(frozen=True)
class EpipolarMatches:
    X: np.ndarray          # (n, 3) world points
    src_xy: np.ndarray     # (n, 2) level-0 pixels in the source keyframe (the patch centre)
    src_level_xy: np.ndarray  # (n, 2) pixels at the source level
    tgt_xy: np.ndarray     # (n, 2) level-0 pixels in the target keyframe (sub-pixel)


def one_pixel_dist(camera) -> float:
    """Unit-plane length of one pixel at the principal point (PTAM code: ``OnePixelDist``)."""
    c = np.array([[camera.cx, camera.cy], [camera.cx + 1.0, camera.cy]])
    xy = camera.unproject(c)
    return float(np.linalg.norm(xy[1] - xy[0]))


def unit_plane_corners(camera, pyramid, level: int) -> np.ndarray:
    """The level's FAST corners on the unit plane (PTAM code caches these per keyframe level)."""
    return camera.unproject(level_to_zero(pyramid.corners[level].astype(np.float64), level))


def _search_boxes(camera, normal, dist, along, lo, hi, level: int, band_px: float, samples: int) -> np.ndarray:
    """Pixel boxes (n, 4) (x0, y0, x1, y1) at ``level`` that hold each search segment's band: the segment is
    sampled on the unit plane, projected through the lens, and the box padded by the band plus the bulge the
    lens can give the curve between two samples (bounded by the sample spacing)."""
    t = np.linspace(0.0, 1.0, samples)
    ts = lo[:, None] + (hi - lo)[:, None] * t[None, :]
    pts = along[:, None, :] * ts[..., None] + (normal * dist[:, None])[:, None, :]
    uv = camera.project(np.concatenate([pts, np.ones(pts.shape[:2] + (1,))], axis=-1).reshape(-1, 3))
    uv = zero_to_level(uv, level).reshape(len(lo), samples, 2)
    step = np.linalg.norm(np.diff(uv, axis=1), axis=2).max(axis=1) if samples > 1 else np.zeros(len(lo))
    pad = (band_px / (1 << level) + 1.0 + 0.5 * step)[:, None]
    lo_xy = np.floor(np.nanmin(uv, axis=1) - pad)
    hi_xy = np.ceil(np.nanmax(uv, axis=1) + pad)
    big = np.iinfo(np.int32).max // 2
    box = np.concatenate([np.clip(lo_xy, -big, big), np.clip(hi_xy, -big, big)], axis=1)
    return np.nan_to_num(box, nan=0.0).astype(np.int64)


def epipolar_matches(camera, T_src, T_tgt, src_pyr, tgt_pyr, depth_mean: float, depth_sigma: float, level: int,
                     cand_xy: np.ndarray, tgt_plane_corners: np.ndarray, cfg) -> EpipolarMatches:
    """Search every candidate (level pixels (n, 2) int in the source keyframe) in the target keyframe."""
    m, p = cfg.mapper, cfg.patch
    wiggle = cfg.init.baseline_m
    empty = EpipolarMatches(np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2)))
    if len(cand_xy) == 0 or len(tgt_pyr.corners[level]) == 0:
        return empty
    cand_xy = np.asarray(cand_xy, np.float64)
    root = level_to_zero(cand_xy, level)
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
    along = a - b
    alen = np.linalg.norm(along, axis=1)
    ok &= np.isfinite(alen) & (alen > m.epipolar_min_line_length)
    along = along / np.where(alen > 0, alen, 1.0)[:, None]
    normal = np.stack([along[:, 1], -along[:, 0]], axis=1)
    dist = (a * normal).sum(axis=1)
    ok &= np.abs(dist) <= camera.max_radius
    ta, tb = (along * a).sum(axis=1), (along * b).sum(axis=1)
    clip = m.epipolar_along_clip
    lo = np.clip(np.minimum(ta, tb) - m.epipolar_along_margin, -clip, clip)
    hi = np.clip(np.maximum(ta, tb) + m.epipolar_along_margin, -clip, clip)
    idx = np.flatnonzero(ok)
    if len(idx) == 0:
        return empty
    n = len(idx)
    src_stack = tuple(im[None] for im in src_pyr.levels)
    templates, tok = make_templates(src_stack, np.zeros(n, np.int32), np.full(n, level, np.int8),
                                    cand_xy[idx], np.broadcast_to(np.eye(2), (n, 2, 2)).copy(), p.size)
    idx, templates = idx[tok], templates[tok]
    n = len(idx)
    if n == 0:
        return empty
    band_px = m.epipolar_band_px + (1 << level)
    max_perp = np.full(n, one_pixel_dist(camera) * band_px)
    max_ssd = p.max_ssd_per_pixel * p.size * p.size
    box = _search_boxes(camera, normal[idx], dist[idx], along[idx], lo[idx], hi[idx], level, band_px,
                        m.epipolar_box_samples)
    best, _ = epipolar_search(tgt_pyr.levels[level], tgt_pyr.corners[level], tgt_plane_corners,
                              tgt_pyr.row_lut[level], box, templates, normal[idx], dist[idx], along[idx], lo[idx],
                              hi[idx], max_perp, max_ssd)
    found = best >= 0
    idx, templates, best = idx[found], templates[found], best[found]
    if len(idx) == 0:
        return empty
    start_xy = tgt_pyr.corners[level][best].astype(np.float64)
    refined, conv = refine_subpix(tgt_pyr.levels, templates, np.full(len(idx), level, np.int8), start_xy,
                                  p.subpix_iterations, p.subpix_converge_px)
    idx, refined = idx[conv], refined[conv]
    tgt_xy = level_to_zero(refined, level)
    X = triangulate_two_view(T_src, T_tgt, camera.unproject(root[idx]), camera.unproject(tgt_xy))
    zs = X @ T_src[2, :3] + T_src[2, 3]
    zt = X @ T_tgt[2, :3] + T_tgt[2, 3]
    good = np.isfinite(X).all(axis=1) & (zs > 0) & (zt > 0)
    return EpipolarMatches(X[good], root[idx][good], cand_xy[idx][good], tgt_xy[good])

