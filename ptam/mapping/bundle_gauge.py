"""Bundle adjustment's free scale, held inside each Levenberg–Marquardt step (``bundle.hold_scale``).

With one keyframe fixed (PTAM's global BA) a monocular map keeps one free degree of freedom: the whole map scaled
about that keyframe's centre changes no point residual, so the points' gradient has no component along it and LM
does not move it. An edgelet's 4-DOF update (Agility §4.4, eq. 9) cannot slide the edgelet along its own line, and
its residuals do change under such a slide wherever the projected edgelet is not exactly parallel to the measured
line, so with edgelets the linearised problem has a gradient along the scale while its curvature there is only the
damping's. The steps then scaled the map by amounts that grew as λ fell (0.1 % per iteration on desk_table's
global adjustments, measured), the convergence test waited on them (11 LM iterations against 3 for points alone on
a desk_corner global BA) and the map came out scaled (``gauge.hold_scale`` undid that afterwards).

``ScaleGauge.step`` solves the damped reduced system S δμ = b under the constraint gᵀ δμ = 0, g the keyframes'
translations under the scaling (g_i = −R_i (C_i − C_0) for free keyframe i): δμ = S⁻¹b − S⁻¹g (gᵀS⁻¹b)/(gᵀS⁻¹g),
both solves on one factorisation. Points and edgelets then follow the keyframes by back-substitution, so the step
is the damped model's best one that does not scale the keyframes, and LM's acceptance test works on it as on any.
Adjustments without edgelets keep PTAM's step: the points' gradient has no component along the scale.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bundle_solve_kernels import ba_gauged_solve
from .bundle_structure import BundleStructure, ReducedSolver, not_positive_definite


@dataclass(frozen=True)
class ScaleGauge:
    """The one fixed keyframe (compact index) whose centre the free scale is taken about."""

    fixed: int

    @staticmethod
    def of(st: BundleStructure) -> ScaleGauge | None:
        """The gauge of a problem with exactly one fixed keyframe and some free ones; None otherwise (two fixed
        keyframes fix the scale)."""
        fixed = np.flatnonzero(~st.free)
        return ScaleGauge(int(fixed[0])) if len(fixed) == 1 and st.n_free else None

    def step(self, solver: ReducedSolver, blocks: np.ndarray, rhs: np.ndarray, P: np.ndarray, free: np.ndarray):
        """The camera step of S δμ = rhs with gᵀ δμ = 0, g the scaling of the keyframes ``free`` at poses ``P``
        (``ba_gauged_solve``); LinAlgError when S does not factorise."""
        lower = (solver.rows, solver.cols, solver.rank, solver.first, solver.ptr)
        x, ok = ba_gauged_solve(blocks, *lower, rhs, P, self.fixed, free)
        if not ok:
            raise not_positive_definite()
        return x
