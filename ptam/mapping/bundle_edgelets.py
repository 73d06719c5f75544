"""The edgelets' part of one bundle adjustment (Agility §4.4): their parameters and per-iteration work arrays.

Every keyframe measurement of an edgelet gives two perpendicular distances ε_n from virtual sample points ±5 px
from its projected centre to the measured line (eq. 6–7); the edgelet's four degrees of freedom (eq. 9) are
eliminated by the Schur complement like a point's three (``bundle_schur_kernels``). An ``EdgeletLM`` without
edgelets adds nothing anywhere, so a points-only adjustment runs exactly as before.

Robust weights. §4.4 chose distances in pixels because it "makes them compatible with the M-Estimator also used
for point features", and §8 gives points and edgelets alike "an independent single-pixel variance": one Tukey
biweight serves both, the edgelets' ε₁² + ε₂² (two pixel-unit residuals per measurement, as a point has) weighed
against the cut-off of the points' σ-normalised |e|² (σ = 2^level), taken from their median as PTAM does
(``bundle.tukey_from_points``). Pooled, the edgelets' line fits, tighter than a patch match, pulled the median
down (on the bench's maps the cut-off from 7.6 to 6.9), and the points' weights then took more iterations to
settle. With no point measured the edgelets' own median gives it. An edgelet measurement beyond the cut-off (or
with a sample point behind the camera) leaves the problem and is reported as an outlier, as a point measurement
is (PTAM §6.4).

The measurement plane. A straight edge projects to a curve in a distorted image, and eq. 7's projections of the
sample points through the lens took most of an edgelet's cost in an iteration (an arctangent each on a FOV lens).
Each measured line is moved once, at the start, to the normalised image plane (``plane_camera``): the point a
unprojected, the normal m̂ pulled back through L, the lens's pixel Jacobian at a. A plane point x is then
g·(x − a) px from the line, g = m̂ᵀL, to first order in |x − a| (the sample points are about 5 px from a, and
there a straight edge's plane image is straight where its lens image bends), and a sample point projects with two
divisions; its pixel distances from the centre (eq. 6) are L's.

Sample points. Eq. 6 places them at ∓5/|d| on the edgelet's axis, |d| its image length per unit length. They are
placed again at every linearisation, from the current state, and kept for that iteration's trial steps (whose costs
are then comparable). At the start |d| is the tangent at the projected centre; after that it is the chord |s₂ − s₁|
/ (z₂ − z₁) of the accepted trial's own two projections, which are at the current state: the two agree to second
order, and where they differ (an edgelet pointing at the camera, its sample points far apart in depth) the chord
puts the pair's mean image offset nearer 5 px (``tests/test_bundle_edgelets.py``). Placed once at the start instead,
they stay fixed in metres while the edgelet turns: an edgelet turning towards its viewing rays brings both closer to
its projected centre, which fits any line through the centre better, and a poorly determined edgelet (nearly
parallel to the baseline) slid that way by tens of degrees over many iterations (measured on the bench's exploring
map). The Jacobians treat them as fixed; the term this leaves out is proportional to the angle between the projected
edgelet and the measured line, which vanishes at the solution.
"""

from __future__ import annotations

import numpy as np

from ..camera.camproj_kernels import UNDISTORT_ITERS, UNDISTORT_TOL
from ..camera.model import KERNEL_PARAMS_LEN, MODEL_IDS, CameraModel
from ..edgelet import Edgelets
from ..edgelet.edgelet_ba_kernels import frames_of
from ..vocabulary import LensModel
from .bundle_edgelet_kernels import (
    ba_edgelet_hold,
    ba_edgelet_linearise_at,
    ba_edgelet_residuals,
    ba_edgelet_rows,
    ba_edgelet_seen_update,
    ba_edgelet_setup,
    ba_edgelet_trial,
)
from .bundle_inputs import EdgeletBundleInput
from .bundle_schur_kernels import ba_backsub, ba_edgelet_schur
from .bundle_structure import BundleStructure, EdgeletStructure


def plane_camera(camera: CameraModel) -> np.ndarray:
    """The kernel parameters of the unit pinhole of ``camera``'s normalised image plane, the lens's range kept (the
    same points are valid): the camera the measured lines are moved to (``ba_edgelet_planes``: the unprojected
    points, the normals g = m̂ᵀL, m̂ the unit normal in the image, and L, the lens's pixel Jacobian at each point;
    numpy reference ``tests/reference/bundle_edgelets.py``)."""
    plane = np.zeros(KERNEL_PARAMS_LEN)
    plane[[0, 1, 2, 10]] = MODEL_IDS[LensModel.PINHOLE], 1.0, 1.0, camera.max_radius
    return plane


_UNDISTORT = (UNDISTORT_ITERS, UNDISTORT_TOL)


class EdgeletLM:
    """The adjusted edgelets (frames E_WE), their measurements and the blocks of the current linearisation."""

    def __init__(
        self, cams: tuple[np.ndarray, np.ndarray], st: BundleStructure, inp: EdgeletBundleInput | None, P: np.ndarray
    ):
        """``cams``: the kernel parameters of the camera and of its normalised plane (``plane_camera``); ``P``: the
        starting poses (compact), at which the sample points are first placed (eq. 6)."""
        es = st.edgelets if st.edgelets is not None and inp is not None else EdgeletStructure.empty()
        self.es = es
        self.n = len(es.sel)
        self.use = np.ones(self.n, bool)
        self.outlier = np.zeros(self.n, bool)
        self.live = np.zeros(self.n, bool)
        self.e2 = np.zeros(self.n)
        self.bad = np.zeros(self.n, bool)
        self.n_use_held = -1
        if inp is None:
            return
        ed = inp.edgelets
        self.F = np.empty((len(es.ids), 4, 4))
        frames_of(ed.centre, ed.direction, ed.normal, es.ids, self.F)  # orthonormal, as every frame a step makes
        self.F0 = self.F.copy()
        self.offset_px = inp.cfg.ba_sample_offset_px
        self.min_plane_angle = np.radians(inp.cfg.triangulate_min_plane_angle_deg)
        # The measured lines on the normalised plane: through a, normal g (not unit: pixels per plane unit).
        image, self.cam = cams
        lines = (inp.obs.a, inp.obs.b, es.sel)
        start = ba_edgelet_setup(image, self.cam, P, self.F, es.mcam, es.medg, lines, *_UNDISTORT, self.offset_px)
        self.a, self.g, self.to_px, self.plane_angle, self.along = start
        self.meas = (es.mcam, es.medg, self.a, self.g)
        self.placed = np.zeros((self.n, 2))
        ne = len(es.ids)
        self.V = np.zeros((ne, 4, 4))
        self.eb = np.zeros((ne, 4))
        self.A = np.zeros((self.n, 2, 6))
        self.B = np.zeros((self.n, 2, 4))
        self.Vinv = np.zeros((ne, 4, 4))
        self.err = np.zeros((self.n, 2))
        self.seen = np.zeros(ne)
        self.jp = np.zeros((self.n, 2, 6))
        self.je = np.zeros((self.n, 2, 4))
        self.terms = (self.err, self.jp, self.je, self.e2, self.bad)  # ``ba_edgelet_rows``' outputs

    def _residuals(self, P: np.ndarray, F: np.ndarray, use: np.ndarray) -> None:
        """e2 and bad (a sample point behind the camera) of the measurements in ``use`` at poses P, frames F, and
        the sample points re-placed there (``placed``)."""
        args = (self.along, self.offset_px, self.to_px, use, self.err, self.e2, self.bad, self.placed)
        ba_edgelet_residuals(self.cam, P, F, self.meas, *args)

    def residuals(self, P: np.ndarray) -> None:
        """The residuals at the current state and their Jacobian rows, at sample points placed at this state (eq. 6):
        by ``ba_edgelet_setup`` at construction, then by the accepted trial, which projected them there. A trial
        keeps the sample points of its linearisation, so that its cost is comparable. ``linearise`` takes them
        itself unless the Tukey cut-off needs these errors first."""
        if self.n:
            ba_edgelet_rows(self.cam, P, self.F, self.meas, self.use, self.along, *self.terms)

    def linearise(self, P: np.ndarray, c2: float, cam_row_blocks: tuple[np.ndarray, np.ndarray], rows: bool) -> float:
        """Add the edgelets' Tukey-weighted terms at the current state (``rows``: not yet taken there by
        ``residuals``) to the camera blocks (U, ε_a); their robust cost."""
        if not self.n:
            return 0.0
        normal = (*cam_row_blocks, self.V, self.eb, self.A, self.B)
        args = (self.along, rows, self.terms, self.use, c2, self.es.mrow, normal, self.live)
        return float(ba_edgelet_linearise_at(self.cam, P, self.F, self.meas, *args))

    def schur(self, lam: float, blocks: np.ndarray, rhs: np.ndarray) -> None:
        if self.n:
            es = self.es
            ba_edgelet_schur(
                self.V,
                self.eb,
                self.A,
                self.B,
                self.live,
                lam,
                es.mrow,
                es.e_start,
                es.order,
                es.pair_id,
                blocks,
                rhs,
                self.Vinv,
            )

    def squared_update(self, de: np.ndarray) -> float:
        """The edgelet updates' share of the convergence test's squared update norm, in the points' unit (metres):
        for each edgelet the largest motion of its sample points that one of its measurements can see, i.e. the
        change of a perpendicular distance (eq. 7) converted to metres at that sample point, at the last
        linearisation (``ba_edgelet_seen_update``). A point's update counts whole (PTAM); an edgelet's parameters
        include directions its measurements hardly see. Where its back-projected planes meet at a few degrees
        (§4.3's aperture problem), it can turn within them and slide along their common line: that changes no
        distance beyond noise, and Marquardt's diagonal damping does not bound it, since the direction is no
        parameter axis. Counted whole, or its turns as the metres they move the sample points, such an edgelet
        swung ±7° from one accepted step to the next and held global BA to the iteration limit (the bench's
        maps of 75 keyframes with a 2° plane-angle gate: 257 LM iterations, 199 with this count)."""
        if not self.n:
            return 0.0
        es = self.es
        return float(ba_edgelet_seen_update(self.jp, self.je, de, es.medg, self.use, self.bad, self.seen))

    def backsub(self, dcam: np.ndarray) -> np.ndarray:
        """The edgelet updates (E, 4) for camera updates ``dcam``."""
        if not self.n:
            return np.zeros((0, 4))
        es = self.es
        return ba_backsub(self.Vinv, self.eb, self.A, self.B, self.live, es.mrow, es.e_start, es.order, dcam)

    def trial(self, P_new: np.ndarray, de: np.ndarray, c2: float) -> tuple[np.ndarray | None, float]:
        """The frames after the step ``de`` and their cost at ``P_new`` on the measurements live at linearisation."""
        if not self.n:
            return None, 0.0
        out = (self.err, self.e2, self.bad, self.placed)
        F_new, cost = ba_edgelet_trial(
            self.cam, P_new, self.F, de, self.meas, self.along, self.offset_px, self.to_px, self.live, out, c2
        )
        return F_new, float(cost)

    def accept(self, F_new: np.ndarray | None) -> None:
        """The accepted trial's frames, and its sample points re-placed at the new state."""
        if F_new is not None:
            self.F = F_new
            self.along, self.placed = self.placed, self.along

    def hold_underdetermined(self) -> None:
        """Edgelets left with fewer than two measurements in the problem are held (``_LMState``'s rule for points),
        and so are those whose measuring keyframes' planes (at the start: ``ba_edgelet_plane_angles``) no longer
        meet at ``triangulate_min_plane_angle_deg`` (``ba_edgelet_hold``): the aperture problem under which §4.3
        would not have made them (their source or target measurement an outlier since). Within such planes the
        line can turn freely, and eq. 6's sample points, placed again at every step, let LM's steps turn it on:
        one edgelet of the bench's maps of 75 keyframes swung 2-12° at every accepted step up to the iteration
        limit when the Tukey cut-off came from the points alone. A held edgelet goes back to where the adjustment
        found it: steps taken before its measurements left (the first one turned that edgelet 49°) were steps in
        an unconstrained direction."""
        # Only measurements leaving the problem can leave an edgelet underdetermined.
        if self.n and int(np.count_nonzero(self.use)) != self.n_use_held:
            es = self.es
            self.n_use_held = ba_edgelet_hold(
                es.medg, self.use, self.plane_angle, self.min_plane_angle, self.F, self.F0
            )

    def flag(self) -> np.ndarray:
        """The measurements that dropped out of the system at the last linearisation."""
        return self.use & ~self.live

    def retire(self, flagged: np.ndarray) -> None:
        self.outlier |= flagged
        self.use &= ~flagged

    def summary(self, P: np.ndarray, inp: EdgeletBundleInput | None, current: bool) -> dict:
        """The adjusted edgelets (all of the input's, rows not adjusted unchanged), the outliers' input indices
        and the inlier count at the returned state (``current``: the accepted trial's residuals are that state's,
        for every measurement still in use)."""
        if inp is None:
            return {}
        out = inp.edgelets
        if self.n:
            if not current:
                self._residuals(P, self.F, self.use)  # at the last linearisation's sample points: no Jacobians needed
            # The frames are orthonormal (``frames_of``, ``frames_updated``).
            centre, direction, normal = out.centre.copy(), out.direction.copy(), out.normal.copy()
            ids = self.es.ids
            centre[ids], direction[ids], normal[ids] = self.F[:, :3, 3], self.F[:, :3, 2], self.F[:, :3, 0]
            out = Edgelets(centre, direction, normal)
        outliers = np.sort(self.es.sel[self.outlier]) if self.n else np.zeros(0, np.int64)
        return {"edgelets": out, "edgelet_outliers": outliers, "n_edgelet_inliers": int((self.use & ~self.bad).sum())}
