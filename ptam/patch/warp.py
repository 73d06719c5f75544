"""The patch warp of PTAM §5.3: pixel vectors on the patch plane, A per point, search level, template matrix.

A map point's patch is an 8×8 square of its source keyframe level, lying on the plane through the point with
the patch normal (PTAM §6.5: initially facing the source camera). ``patch_pixel_vectors`` back-projects one
source-level pixel right and down from the patch centre onto that plane (PTAM code
``MapPoint::RefreshPixelVectors``); they depend only on the map, so the tracker keeps them in a
:class:`PixelVectorCache` and recomputes only the points whose inputs a new snapshot changed.
``ptam.patch.warp_kernels`` projects them into the current view to get A and the search level.
"""

from __future__ import annotations

import numpy as np

from .template_kernels import make_templates
from .warp_kernels import RULES, warp_matrices


def patch_pixel_vectors(camera, kf_T_cw, X, normal, source_kf, source_level, source_xy):
    """World-frame displacements (M, 3), (M, 3) of one source-level pixel right / down on each patch plane."""
    if len(X) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    T = kf_T_cw[source_kf]
    R = T[:, :3, :3]
    s = np.exp2(source_level.astype(np.float64))[:, None]
    uv0 = (source_xy + 0.5) * s - 0.5
    zero = np.zeros_like(s)
    uv = np.stack([uv0, uv0 + np.concatenate([s, zero], axis=1), uv0 + np.concatenate([zero, s], axis=1)], axis=1)
    rays = np.concatenate([camera.unproject(uv.reshape(-1, 2)), np.ones((uv.size // 2, 1))], axis=1)
    rays = rays.reshape(-1, 3, 3)  # centre, one right, one down
    Xc = np.einsum("mij,mj->mi", R, X) + T[:, :3, 3]
    n_c = np.einsum("mij,mj->mi", R, normal)
    height = np.abs(np.einsum("mi,mi->m", Xc, n_c))
    on_plane = rays * (height[:, None] / np.abs(np.einsum("mki,mi->mk", rays, n_c)))[..., None]
    right_c = on_plane[:, 1] - on_plane[:, 0]
    down_c = on_plane[:, 2] - on_plane[:, 0]
    return np.einsum("mji,mj->mi", R, right_c), np.einsum("mji,mj->mi", R, down_c)


class PixelVectorCache:
    """:func:`patch_pixel_vectors` of the newest snapshot, recomputed only for points that are new or whose
    position, normal, source or source keyframe pose changed. Where frames keep coming the mapper publishes after
    every step (a local BA moves a few hundred points, a refind none), and recomputing every point of a
    15,000-point map (~4.5 ms) on each new snapshot was the largest part of the tracker's projection stage. The
    rows are those a full recomputation gives (the function is row by row)."""

    _INPUTS = ("X", "normal", "source_kf", "source_level", "source_xy")

    def __init__(self, camera):
        self.camera = camera
        self._of = None
        self.right = np.zeros((0, 3))
        self.down = np.zeros((0, 3))

    def vectors(self, snapshot) -> tuple[np.ndarray, np.ndarray]:
        if snapshot is self._of:
            return self.right, self.down
        stale = self._stale(snapshot)
        n = len(snapshot.X)
        k = min(n, len(self.right))
        right, down = np.empty((n, 3)), np.empty((n, 3))
        right[:k], down[:k] = self.right[:k], self.down[:k]
        rows = np.flatnonzero(stale)
        right[rows], down[rows] = patch_pixel_vectors(
            self.camera, snapshot.kf_T_cw, *(getattr(snapshot, name)[rows] for name in self._INPUTS)
        )
        self._of, self.right, self.down = snapshot, right, down
        return right, down

    def _stale(self, s) -> np.ndarray:
        n = len(s.X)
        stale = np.ones(n, bool)
        old = self._of
        if old is None:
            return stale
        k = min(n, len(old.X))
        same = np.ones(k, bool)
        for name in self._INPUTS:
            a, b = getattr(s, name)[:k], getattr(old, name)[:k]
            same &= (a == b).reshape(k, -1).all(axis=1)
        nk = min(len(s.kf_T_cw), len(old.kf_T_cw))
        kf_moved = np.ones(len(s.kf_T_cw), bool)
        kf_moved[:nk] = (s.kf_T_cw[:nk] != old.kf_T_cw[:nk]).reshape(nk, -1).any(axis=1)
        stale[:k] = ~same | kf_moved[s.source_kf[:k]]
        return stale


def search_warps(cam_params, patch_cfg, n_levels: int, T_cw, Xc, right_W, down_W):
    """A (n, 2, 2) and search level (n,), −1 where the warp is rejected (PTAM §5.3)."""
    A, _, level = warp_matrices(
        cam_params,
        np.ascontiguousarray(T_cw, dtype=np.float64),
        Xc,
        np.ascontiguousarray(right_W),
        np.ascontiguousarray(down_W),
        n_levels,
        float(patch_cfg.det_min),
        float(patch_cfg.det_max),
        RULES[patch_cfg.search_level_rule],
    )
    return A, level


def template_matrices(A, level):
    """M = A⁻¹·2^l: one search-level pixel in source-level pixels (PTAM §5.3: the template uses A/2^l)."""
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
    scale = np.exp2(level.astype(np.float64)) / det
    M = np.empty_like(A)
    M[:, 0, 0] = A[:, 1, 1] * scale
    M[:, 0, 1] = -A[:, 0, 1] * scale
    M[:, 1, 0] = -A[:, 1, 0] * scale
    M[:, 1, 1] = A[:, 0, 0] * scale
    return M


def unwarped_templates(pyr, level: int, level_xy: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Templates of ``pyr`` centred on ``level_xy`` (pixels at ``level``) with the identity warp (PTAM code
    ``MakeTemplateCoarseNoWarp``), and which of them lie inside the image."""
    n = len(level_xy)
    stack = tuple(im[None] for im in pyr.levels)
    eye = np.broadcast_to(np.eye(2), (n, 2, 2)).copy()
    return make_templates(stack, np.zeros(n, np.int32), np.full(n, level, np.int8), level_xy, eye, size)
