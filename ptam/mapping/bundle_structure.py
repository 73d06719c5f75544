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
from .bundle_schur_kernels import ba_pair_script
from .bundle_solve_kernels import ba_envelope, ba_envelope_solve
from .bundle_structure_kernels import landmark_layout


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
    edgelets: EdgeletStructure | None = None  # Agility §4.4: the edgelets' part, when there are edgelets

    @property
    def n_free(self) -> int:
        return int(self.free.sum())


@dataclass(frozen=True)
class EdgeletStructure:
    """The edgelets of one adjustment, laid out like the points (Agility §4.4: 4-DOF blocks eliminated alike)."""

    ids: np.ndarray  # (Ec,) input indices of the adjusted edgelets with a measurement
    sel: np.ndarray  # (Kec,) input indices of the edgelet measurements in the problem
    mcam: np.ndarray  # (Kec,) compact camera of each measurement
    medg: np.ndarray  # (Kec,) compact edgelet of each measurement
    mrow: np.ndarray  # (Kec,) cam_row[mcam]
    order: np.ndarray  # (Kec,) measurements sorted by edgelet, then camera row
    e_start: np.ndarray  # (Ec + 1,) edgelet e's measurements are order[e_start[e]:e_start[e + 1]]
    pair_id: np.ndarray  # block index of each camera pair in the edgelets' part of ba_pair_script's walk

    @staticmethod
    def empty() -> EdgeletStructure:
        z = np.zeros(0, np.int64)
        return EdgeletStructure(z, z, z, z, z, z, np.zeros(1, np.int64), z)


def _compact(idx: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(idx, return_inverse=True)`` for indices in [0, n), in O(len(idx) + n): numpy 2.4's np.unique
    took 7x (with the inverse) to 20x (without) as long as a sort on a global BA's 33 000 measurements."""
    present = np.zeros(n, bool)
    present[idx] = True
    rank = np.cumsum(present) - 1
    return np.flatnonzero(present), rank[idx].astype(np.int64)


def _landmarks(
    lm: np.ndarray, mcam: np.ndarray, mrow: np.ndarray, n_lm: int, n_cams: int, what: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """The landmarks (< ``n_lm``) measured, each measurement's compact landmark, the measurements by landmark then
    camera row, where each landmark's run starts and the camera-pair walk's entries (``landmark_layout``); refuses a
    keyframe measuring one twice."""
    ids, mlm, order, start, n_entries, ok = landmark_layout(lm, mcam, mrow, n_lm, max(n_cams, 1))
    if not ok:
        raise InputError(f"bundle adjustment: a keyframe measures the same {what} twice")
    return ids, mlm, order, start, int(n_entries)


def seen_twice(mlm: np.ndarray, use: np.ndarray, n: int) -> np.ndarray:
    """Per measurement: its landmark (of ``n``) has at least two measurements in ``use``."""
    return np.bincount(mlm[use], minlength=n)[mlm] >= 2


def _with_edgelets(esel, eid, n_edgelets: int, emcam, cam_row, points: tuple, n_free: int):
    """The edgelets' structure and the camera pairs of one walk over the points and then the edgelets, which
    numbers every pair that either shares; returns (edgelet structure, points' pair ids, pair rows, columns)."""
    mrow, order, pt_start, n_pt = points
    emrow = cam_row[emcam]
    ids, medg, eorder, e_start, _ = _landmarks(eid, emcam, emrow, n_edgelets, len(cam_row), "edgelet")
    pair_id, rows, cols = ba_pair_script(
        np.concatenate([pt_start, pt_start[-1] + e_start[1:]]),
        np.concatenate([order, len(mrow) + eorder]),
        np.concatenate([mrow, emrow]),
        n_free,
    )
    edg = EdgeletStructure(ids, esel, emcam, medg, emrow, eorder, e_start, n_free + pair_id[n_pt:])
    return edg, pair_id[:n_pt], rows, cols


def build_structure(
    meas_kf: np.ndarray,
    meas_pt: np.ndarray,
    fixed_poses: np.ndarray,
    adjust_points: np.ndarray,
    edgelet_meas: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> BundleStructure:
    """Only measurements of points in ``adjust_points`` take part (PTAM eq. 11: j ∈ Z). ``edgelet_meas``: the
    keyframe and edgelet of every edgelet measurement and the edgelets to adjust (Agility §4.4), or None."""
    sel = np.flatnonzero(adjust_points[meas_pt])
    esel = np.zeros(0, np.int64) if edgelet_meas is None else np.flatnonzero(edgelet_meas[2][edgelet_meas[1]])
    ekf, eid = (np.zeros(0, np.int64),) * 2 if edgelet_meas is None else (edgelet_meas[0][esel], edgelet_meas[1][esel])
    cams, inverse = _compact(np.concatenate([meas_kf[sel], ekf]), len(fixed_poses))
    mcam, emcam = inverse[: len(sel)], inverse[len(sel) :]
    free = ~fixed_poses[cams]
    n_free = int(free.sum())
    cam_row = np.full(len(cams), -1, np.int64)
    cam_row[free] = np.arange(n_free)
    mrow = cam_row[mcam]
    pts, mpt, order, pt_start, n_pt = _landmarks(meas_pt[sel], mcam, mrow, len(adjust_points), len(cams), "point")
    if edgelet_meas is None:
        edg = None
        pair_id, rows, cols = ba_pair_script(pt_start, order, mrow, n_free)
    else:
        points = (mrow, order, pt_start, n_pt)
        edg, pair_id, rows, cols = _with_edgelets(esel, eid, len(edgelet_meas[2]), emcam, cam_row, points, n_free)
    diag = np.arange(n_free, dtype=np.int64)
    return BundleStructure(
        cams=cams,
        free=free,
        cam_row=cam_row,
        pts=pts,
        sel=sel,
        mcam=mcam,
        mpt=mpt,
        mrow=mrow,
        order=order,
        pt_start=pt_start,
        pair_rows=np.concatenate([diag, rows]),
        pair_cols=np.concatenate([diag, cols]),
        pair_id=n_free + pair_id,
        edgelets=edg,
    )


def not_positive_definite() -> np.linalg.LinAlgError:
    """The error of a reduced camera system that does not factorise (PTAM code: "the map is probably corrupt")."""
    return np.linalg.LinAlgError("bundle adjustment: reduced camera system is not positive definite")


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
        """x with S x = rhs, for one right-hand side (n,) or several (n, k) on one factorisation."""
        rhs2 = np.ascontiguousarray(rhs, dtype=np.float64).reshape(len(rhs), -1)
        x, ok = ba_envelope_solve(blocks, self.rows, self.cols, self.rank, self.first, self.ptr, rhs2)
        if not ok:
            raise not_positive_definite()
        return x.reshape(np.shape(rhs))
