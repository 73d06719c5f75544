"""The sparsity structure of one bundle adjustment and the solvers of its reduced camera system (PTAM §6.3).

Built once per ``Bundle.adjust`` call: the cameras and points that take part, measurements sorted by point
(then camera), and the camera pairs that share a point (PTAM code: ``GenerateOffDiagScripts``). The
reduced system S δμ = rhs (poses only, points eliminated by the Schur complement) is solved by a dense
Cholesky up to ``bundle.dense_max_cameras`` free keyframes and by a sparse (envelope) Cholesky beyond.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from ..errors import InputError
from .bundle_kernels import ba_pair_script
from .bundle_solve_kernels import ba_envelope, ba_envelope_solve


@dataclass(frozen=True)
class BundleStructure:
    cams: np.ndarray  # (Nc,) input indices of the keyframes with a measurement in the problem
    free: np.ndarray  # (Nc,) bool, adjusted (not fixed)
    cam_row: np.ndarray  # (Nc,) block row of a free camera in S, −1 when fixed
    pts: np.ndarray  # (Mc,) input indices of the adjusted points with a measurement
    sel: np.ndarray  # (Kc,) input indices of the measurements in the problem
    mcam: np.ndarray  # (Kc,) compact camera of each measurement
    mpt: np.ndarray  # (Kc,) compact point of each measurement
    mrow: np.ndarray  # (Kc,) cam_row[mcam]
    order: np.ndarray  # (Kc,) measurements sorted by point, then camera row
    pt_start: np.ndarray  # (Mc + 1,) point p's measurements are order[pt_start[p]:pt_start[p + 1]]
    pair_rows: np.ndarray  # (B,) block row of each block of S (the first n_free are the diagonal)
    pair_cols: np.ndarray  # (B,) block column (≤ row: S is stored as its lower triangle)
    pair_id: np.ndarray  # block index of each camera pair in ba_pair_script's walk

    @property
    def n_free(self) -> int:
        return int(self.free.sum())


def build_structure(
    meas_kf: np.ndarray, meas_pt: np.ndarray, fixed_poses: np.ndarray, adjust_points: np.ndarray
) -> BundleStructure:
    """Only measurements of points in ``adjust_points`` take part (PTAM eq. 11: j ∈ Z)."""
    sel = np.flatnonzero(adjust_points[meas_pt])
    cams, mcam = np.unique(meas_kf[sel], return_inverse=True)
    pts, mpt = np.unique(meas_pt[sel], return_inverse=True)
    pair_key = mpt.astype(np.int64) * max(len(cams), 1) + mcam
    if len(np.unique(pair_key)) != len(sel):
        raise InputError("bundle adjustment: a keyframe measures the same point twice")
    free = ~fixed_poses[cams]
    n_free = int(free.sum())
    cam_row = np.full(len(cams), -1, np.int64)
    cam_row[free] = np.arange(n_free)
    mrow = cam_row[mcam]
    order = np.lexsort((mrow, mpt)).astype(np.int64)
    pt_start = np.concatenate([[0], np.cumsum(np.bincount(mpt, minlength=len(pts)))]).astype(np.int64)
    pair_id, rows, cols = ba_pair_script(pt_start, order, mrow, n_free)
    diag = np.arange(n_free, dtype=np.int64)
    return BundleStructure(
        cams=cams,
        free=free,
        cam_row=cam_row,
        pts=pts,
        sel=sel,
        mcam=mcam.astype(np.int64),
        mpt=mpt.astype(np.int64),
        mrow=mrow,
        order=order,
        pt_start=pt_start,
        pair_rows=np.concatenate([diag, rows]),
        pair_cols=np.concatenate([diag, cols]),
        pair_id=n_free + pair_id,
    )


class ReducedSolver:
    """Cholesky of the reduced camera system S (PTAM code: TooN ``Cholesky<>`` of the dense 6N×6N matrix).

    ``dense``: the whole lower triangle in keyframe order. Otherwise sparse: the keyframes are reordered by
    reverse Cuthill–McKee on the keyframe graph (once per adjustment) and only S's envelope is stored and
    factorised, which is what fills in. Both run in one GIL-free numba kernel; SuperLU would need its own
    orderings (which hold the GIL) and LAPACK brings OpenBLAS threads that fight the tracker for the cores.
    """

    def __init__(self, st: BundleStructure, dense: bool):
        n_free = st.n_free
        self.rows, self.cols = st.pair_rows, st.pair_cols
        if dense:
            self.rank = np.arange(n_free, dtype=np.int64)
        else:
            graph = sp.coo_matrix((np.ones(len(self.rows)), (self.rows, self.cols)), shape=(n_free, n_free))
            perm = reverse_cuthill_mckee((graph + graph.T).tocsr(), symmetric_mode=True)
            self.rank = np.empty(n_free, np.int64)
            self.rank[perm] = np.arange(n_free)
        self.first, self.ptr = ba_envelope(self.rows, self.cols, self.rank, dense)

    @property
    def stored(self) -> int:
        """Entries of L stored (the envelope's size)."""
        return int(self.ptr[-1])

    def solve(self, blocks: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        x, ok = ba_envelope_solve(blocks, self.rows, self.cols, self.rank, self.first, self.ptr, rhs)
        if not ok:
            raise np.linalg.LinAlgError("bundle adjustment: reduced camera system is not positive definite")
        return x
