"""Estimation of feature normals in the mapper's background (Gauglitz et al. TVCG 2013 §5.4).

PTAM gives a new point a patch normal facing its source camera (PTAM §6.5); the tracker warps every patch
with the point's normal (``ptam.patch.warp``), so a better normal predicts the patch's appearance better.
Gauglitz §5.4 estimates it per feature: the patch of one view is aligned to another view by
inverse-compositional affine alignment (``normals_kernels``), and the normal is read off eq. (1),

    H⊥ ∝ (nᵀx)·R + t·nᵀ     (X₂ = R·X₁ + t; x the point in view 1, n its normal, both in view 1's frame),

the homography its plane induces between the views. The affine is H⊥'s linearisation at the point, carried
through each view's lens model (the cameras' projection Jacobians), so its four linear entries give four
homogeneous equations linear in n (the translation is fixed by x itself); n is the null vector of that
over-determined system, by SVD. An alignment that does not converge gives no estimate, and neither does a
normal facing away from either camera. Independent estimates from random pairs of views are averaged (the
sum of unit estimates and their count per point); the average replaces the map's normal.

Pairs are the point's source keyframe (where its patch lives) and another keyframe that measures it, each
pair aligned once; the estimator keeps its accumulators in the source keyframe's camera frame, so bundle
adjustment and ``Map.transform`` carry the estimates along with the keyframe.
"""

from __future__ import annotations

import time

import numpy as np

from ..patch.finder import frozen
from ..patch.warp import patch_pixel_vectors
from .normals_kernels import align_affine

_KEY = np.int64(1) << 32  # pair key = point index · _KEY + keyframe index


def _level_scale(level) -> np.ndarray:
    return np.exp2(np.asarray(level, dtype=np.float64))


def _rel_pose(T1, T2):
    """R, t with X₂ = R·X₁ + t, from world-to-camera poses (M, 4, 4)."""
    R = T2[:, :3, :3] @ np.transpose(T1[:, :3, :3], (0, 2, 1))
    t = T2[:, :3, 3] - np.einsum("mij,mj->mi", R, T1[:, :3, 3])
    return R, t


def _camera_points(T, X):
    return np.einsum("mij,mj->mi", T[:, :3, :3], X) + T[:, :3, 3]


def _pixel_per_normalised(camera, Xc):
    """∂(u, v)/∂(x/z, y/z) (M, 2, 2) at camera-frame points: the lens model's Jacobian on the z = 1 plane."""
    return camera.project_jacobian(Xc / Xc[:, 2:3])[:, :, :2]


def initial_warps(camera, n_levels, kf_T_cw, T2, X, normal, source_kf, source_level, source_xy):
    """The patch warp the current normal predicts (PTAM §5.3): A (M, 2, 2) in target-level pixels per
    source-level pixel, and the target level whose pixels match the source's in area best, −1 if none."""
    right, down = patch_pixel_vectors(camera, kf_T_cw, X, normal, source_kf, source_level, source_xy)
    J = camera.project_jacobian(_camera_points(T2, X))
    R = T2[:, :3, :3]
    A = J @ np.stack([np.einsum("mij,mj->mi", R, right), np.einsum("mij,mj->mi", R, down)], axis=-1)
    det = np.linalg.det(A)
    with np.errstate(divide="ignore", invalid="ignore"):
        level = np.clip(np.rint(np.log(det) / np.log(4.0)), 0, n_levels - 1)
    level = np.where(det > 0, level, -1).astype(np.int32)
    return A / _level_scale(np.maximum(level, 0))[:, None, None], level


def normals_from_affines(camera, T1, T2, X, A):
    """Eq. (1) by SVD: the unit normal (M, 3) in view 1's camera frame of the plane whose homography has the
    level-0 pixel affine ``A`` (M, 2, 2) at the point X (world), and whether it faces both cameras."""
    Xc1, Xc2 = _camera_points(T1, X), _camera_points(T2, X)
    R, t = _rel_pose(T1, T2)
    # The affine between the views' normalised planes (lens distortion removed at both ends).
    J = np.linalg.solve(_pixel_per_normalised(camera, Xc2), A) @ _pixel_per_normalised(camera, Xc1)
    P = np.zeros((len(X), 2, 3))
    P[:, 0, 0] = P[:, 1, 1] = 1.0
    P[:, :, 2] = -Xc2[:, :2] / Xc2[:, 2:3]
    # y₃·J = P·H[:, :2] with y₃ = (nᵀx)·z₂/z₁: row (i, j) is x·((z₂/z₁)·J_ij − (P·R)_ij) − (P·t)_i·e_j.
    coef = (Xc2[:, 2] / Xc1[:, 2])[:, None, None] * J - (P @ R)[:, :, :2]
    Pt = np.einsum("mij,mj->mi", P, t)
    B = coef[..., None] * Xc1[:, None, None, :]
    B[:, :, 0, 0] -= Pt
    B[:, :, 1, 1] -= Pt
    n = np.linalg.svd(B.reshape(-1, 4, 3))[2][:, -1]
    n *= -np.sign(np.einsum("mi,mi->m", n, Xc1))[:, None]
    facing = (np.einsum("mi,mi->m", n, Xc1) < 0) & (np.einsum("mi,mi->m", np.einsum("mij,mj->mi", R, n), Xc2) < 0)
    return n, facing


def estimate_normals(camera, cfg, n_levels, kf_T_cw, kf_images, X, normal, source, tgt_kf, tgt_xy):
    """One alignment per pair (source keyframe, ``tgt_kf``) of the points X with the map's ``normal`` and
    ``source`` = (source_kf, source_level, source_xy), measured at level-0 ``tgt_xy`` in ``tgt_kf``. Returns the
    estimates (M, 3) in each source camera's frame and whether each is one (converged and facing both views)."""
    source_kf, source_level, source_xy = source
    T1, T2 = kf_T_cw[source_kf], kf_T_cw[tgt_kf]
    A0, level = initial_warps(camera, n_levels, kf_T_cw, T2, X, normal, source_kf, source_level, source_xy)
    ok = level >= 0
    lv = np.maximum(level, 0)
    A, _, converged, ncc = align_affine(
        frozen(kf_images),
        source_kf.astype(np.int32),
        source_level.astype(np.int8),
        np.ascontiguousarray(source_xy, dtype=np.float64),
        tgt_kf.astype(np.int32),
        lv.astype(np.int8),
        np.ascontiguousarray(A0),
        (tgt_xy + 0.5) / _level_scale(lv)[:, None] - 0.5,
        int(cfg.patch_size),
        int(cfg.max_iterations),
        float(cfg.converge_px),
    )
    ok &= converged & (ncc >= cfg.min_ncc)
    A_level0 = A * (_level_scale(lv) / _level_scale(source_level))[:, None, None]
    n = np.zeros((len(X), 3))
    if ok.any():
        n[ok], facing = normals_from_affines(camera, T1[ok], T2[ok], X[ok], A_level0[ok])
        ok[ok] = facing
    return n, ok


class NormalEstimator:
    """Gauglitz §5.4 in the mapper's background, a batch of points per call (``MapMaker.step``'s last job).

    ``has_work``: some good, non-ray point has a pair of keyframes (its source and another that measures it,
    seen with ``min_parallax_deg`` or more between the rays) not aligned yet, and fewer than
    ``estimates_per_point`` attempts. ``run_batch`` aligns one random such pair for each of up to
    ``batch_points`` points (fewest attempts first) and writes the averaged normal of every point with at least
    ``min_estimates`` estimates into the map. ``stats``: batches, pairs aligned, estimates, seconds.
    """

    def __init__(self, camera, cfg) -> None:
        self.camera = camera
        self.cfg = cfg.normals
        self.n_levels = cfg.image.levels
        self._rng = np.random.default_rng(self.cfg.seed)
        self._sum = np.zeros((0, 3))  # per point: sum of unit estimates, source camera frame
        self._count = np.zeros(0, np.int64)
        self._attempts = np.zeros(0, np.int64)
        self._tried = np.zeros(0, np.int64)  # sorted keys of the pairs aligned already
        self._due_version = -1
        self._due_meas = np.zeros(0, np.int64)
        self.stats = {"batches": 0, "aligned": 0, "estimates": 0, "seconds": 0.0}

    def has_work(self, m) -> bool:
        return len(self._due(m)) > 0

    def run_batch(self, m) -> int:
        """Align one batch of pairs of the map ``m``; returns the number of estimates made."""
        start = time.perf_counter()
        meas = self._pick(m, self._due(m))
        if len(meas) == 0:
            return 0
        pts, kfs = m.meas_pt[meas].astype(np.int64), m.meas_kf[meas].astype(np.int64)
        self._tried = np.union1d(self._tried, pts * _KEY + kfs)
        self._due_version = -1
        source = (m.source_kf[pts], m.source_level[pts], m.source_xy[pts])
        n, ok = estimate_normals(
            self.camera,
            self.cfg,
            self.n_levels,
            m.kf_T_cw,
            m.kf_images,
            m.X[pts],
            m.normal[pts],
            source,
            kfs,
            m.meas_xy[meas],
        )
        np.add.at(self._attempts, pts, 1)
        np.add.at(self._sum, pts[ok], n[ok])
        np.add.at(self._count, pts[ok], 1)
        self._write(m, np.unique(pts[ok]))
        self.stats["batches"] += 1
        self.stats["aligned"] += len(meas)
        self.stats["estimates"] += int(ok.sum())
        self.stats["seconds"] += time.perf_counter() - start
        return int(ok.sum())

    def _write(self, m, pts: np.ndarray) -> None:
        pts = pts[self._count[pts] >= self.cfg.min_estimates]
        if len(pts) == 0:
            return
        n_c = self._sum[pts] / np.linalg.norm(self._sum[pts], axis=1, keepdims=True)
        R = m.kf_T_cw[m.source_kf[pts], :3, :3]
        m.set_normals(pts, np.einsum("mji,mj->mi", R, n_c))

    def _grow(self, n: int) -> None:
        have = len(self._count)
        if n > have:
            self._sum = np.concatenate([self._sum, np.zeros((n - have, 3))])
            self._count = np.concatenate([self._count, np.zeros(n - have, np.int64)])
            self._attempts = np.concatenate([self._attempts, np.zeros(n - have, np.int64)])

    def _due(self, m) -> np.ndarray:
        """Indices of the measurements whose (point, keyframe) pairs are left to align (cached per map version)."""
        if m.version == self._due_version:
            return self._due_meas
        self._grow(m.n_points_total)
        kf, pt = m.meas_kf, m.meas_pt
        src = m.source_kf[pt]
        ok = (kf != src) & ~m.bad[pt] & ~m.ray[pt] & (self._attempts[pt] < self.cfg.estimates_per_point)
        idx = np.flatnonzero(ok)
        idx = idx[~np.isin(pt[idx].astype(np.int64) * _KEY + kf[idx], self._tried)]
        C, X = m.camera_centres, m.X[pt[idx]]
        r1, r2 = C[src[idx]] - X, C[kf[idx]] - X
        cos = np.einsum("mi,mi->m", r1, r2) / (np.linalg.norm(r1, axis=1) * np.linalg.norm(r2, axis=1))
        self._due_meas = idx[cos <= np.cos(np.radians(self.cfg.min_parallax_deg))]
        self._due_version = m.version
        return self._due_meas

    def _pick(self, m, due: np.ndarray) -> np.ndarray:
        """One random due pair per point, for the ``batch_points`` points with the fewest attempts."""
        if len(due) == 0:
            return due
        shuffled = due[self._rng.permutation(len(due))]
        pts = m.meas_pt[shuffled]
        _, first = np.unique(pts, return_index=True)
        order = np.lexsort((first, self._attempts[pts[first]]))
        return shuffled[first[order[: self.cfg.batch_points]]]
