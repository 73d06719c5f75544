"""Bundle-adjustment kernels for edgelets: their 4-DOF blocks in PTAM's Schur-complement LM (Agility §4.4).

An edgelet is eliminated exactly like a point (PTAM §6.3, Hartley & Zisserman A6.4), with 4×4 blocks
instead of 3×3: per measurement the two perpendicular distances ε_n (eq. 7) and their Jacobians ∂ε/∂μ_K (2×6,
eq. 8) and ∂ε/∂μ_E (2×4, eq. 9), as ``ptam.edgelet.edgelet_ba_kernels.edgelet_ba_terms`` has them, are weighted by
the Tukey biweight and accumulated:

* ``ba_edgelet_planes``: the measured lines moved, once, to the normalised image plane (``bundle_edgelets``).
* ``ba_edgelet_place``: the two virtual sample points of eq. 6, ±5 px from the projected centre, at the start.
* ``ba_edgelet_setup``: those two and ``ba_edgelet_plane_angles`` (below) in one call at the start.
* ``ba_edgelet_rows``: at each linearisation, ε, |ε|² (the Tukey cut-off's input) and the Jacobian rows at those
  sample points, in one pass over the measurements (each sample point is projected once).
* ``ba_edgelet_residuals``: ε and |ε|² alone, at the sample points of the linearisation (the trial steps' cost),
  and the sample points placed again at the trial's state from the same two projections, for the linearisation
  that follows if the trial is accepted. The centre's own projection and its Jacobian (``_along``) are then needed
  only at the start: per iteration an edgelet measurement costs four projections instead of five.
* ``ba_edgelet_linearise_at``, ``ba_edgelet_trial``: a linearisation and a trial step, each in one call.
* ``ba_edgelet_linearise``: from those rows and the Tukey cut-off, camera blocks U (6×6, added to the points' U),
  edgelet blocks V (4×4), the gradients ε_a, ε_b and the weighted rows A (2×6), B (2×4) whose product AᵀB is the
  camera-edgelet block W. ε is predicted − measured, the points' error measured − predicted; the gradients take
  −ε so that one step solves both.
* ``bundle_schur_kernels.ba_edgelet_schur``: S −= Σ W V*⁻¹ Wᵀ over every camera pair that shares an edgelet and
  the reduced right-hand side, as for points.
* the edgelet updates δμ_E = V*⁻¹ (ε_b − Σ Wᵀ δμ_K) are ``bundle_schur_kernels.ba_backsub``'s, as for points;
  ``ptam.edgelet.edgelet_ba_kernels.frames_updated`` applies them to the frames (``Edgelets.updated``).
* ``ba_edgelet_seen_update``: the edgelet updates' share of the convergence test, the motion of their sample points
  that the measurements can see (``bundle_edgelets.EdgeletLM.squared_update``).
* ``ba_edgelet_plane_angles``, ``ba_edgelet_hold``: the planes through each edgelet and its measuring keyframes'
  centres, once per adjustment, and the hold of edgelets left with one measurement or in §4.3's aperture problem
  (``bundle_edgelets.EdgeletLM.hold_underdetermined``).

``cam`` is the camera the measured lines are in: the image itself (``to_px`` the identity), or, as
``bundle_edgelets`` runs them, the normalised image plane of a unit pinhole, where a straight edge is straight and
its sample points project with two divisions instead of through the lens (``to_px`` the lens's pixel Jacobian at
each measurement). Per Agility §8 every distance has unit (one-pixel) variance. The numpy references are in
``tests/reference/bundle_edgelets.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..camera.camproj_kernels import distort, project, project_jac, undistort
from ..edgelet.edgelet_ba_kernels import axis_in_camera, frames_updated, measurement_rows
from ..edgelet.edgelet_triangulation_kernels import camera_centre
from .bundle_kernels import ba_robust_cost, clear_residual


@njit(nogil=True, cache=True, inline="always")
def _pixels(to_px, du, dv):
    """The length in pixels of the step (du, dv) in the measurement's plane, ``to_px`` its 2×2 Jacobian there."""
    pu = to_px[0, 0] * du + to_px[0, 1] * dv
    pv = to_px[1, 0] * du + to_px[1, 1] * dv
    return math.sqrt(pu * pu + pv * pv)


@njit(nogil=True, cache=True)
def ba_edgelet_planes(cam, a, b, iters, tol, xy, g, to_px):
    """Each measured line, through ``a`` (M, 2) px along ``b`` (M, 2), on the normalised image plane
    (``bundle_edgelets.plane_camera``): ``xy`` (M, 2) the unprojected a (``undistort``'s ``iters``, ``tol``),
    ``to_px`` (M, 2, 2) the lens's pixel Jacobian there and ``g`` (M, 2) = m̂ᵀ to_px, m̂ = perp(b)/|b| the line's
    unit normal."""
    fx, fy = cam[1], cam[2]
    for k in range(a.shape[0]):
        x, y = undistort(cam, (a[k, 0] - cam[3]) / fx, (a[k, 1] - cam[4]) / fy, iters, tol)
        _, _, ja, jb, jc, jd = distort(cam, x, y)
        xy[k, 0] = x
        xy[k, 1] = y
        to_px[k, 0, 0] = fx * ja
        to_px[k, 0, 1] = fx * jb
        to_px[k, 1, 0] = fy * jc
        to_px[k, 1, 1] = fy * jd
        norm = math.sqrt(b[k, 0] * b[k, 0] + b[k, 1] * b[k, 1])
        m0 = -b[k, 1] / norm
        m1 = b[k, 0] / norm
        g[k, 0] = m0 * to_px[k, 0, 0] + m1 * to_px[k, 1, 0]
        g[k, 1] = m0 * to_px[k, 0, 1] + m1 * to_px[k, 1, 1]


@njit(nogil=True, cache=True, inline="always")
def _along(cam, T, E, offset_px, to_px, J):
    """Eq. 6: the E-frame z of the sample points ±``offset_px`` px from the projected centre (∓z, z), z =
    ``offset_px``/|d|, |d| the image length of a unit step along the edgelet (eq. 5) at its centre; 0 when the
    centre is behind the camera."""
    X, Y, Z, dx, dy, dz = axis_in_camera(T, E)
    _, _, ok = project_jac(cam, X, Y, Z, J)
    if not ok:
        return 0.0
    du = J[0, 0] * dx + J[0, 1] * dy + J[0, 2] * dz
    dv = J[1, 0] * dx + J[1, 1] * dy + J[1, 2] * dz
    return offset_px / max(_pixels(to_px, du, dv), 1e-12)


@njit(nogil=True, cache=True)
def ba_edgelet_place(cam, poses, frames, mcam, medg, offset_px, to_px, along):
    """Eq. 6 at the start of an adjustment: each measurement's sample points ±``offset_px`` px from its projected
    centre, from the image length |d| of a unit step along the edgelet there (``along`` (M, 2)); ``to_px`` (M, 2, 2)
    the pixels per unit of ``cam``'s image at each measurement."""
    J = np.empty((2, 3))
    for k in range(mcam.shape[0]):
        z = _along(cam, poses[mcam[k]], frames[medg[k]], offset_px, to_px[k], J)
        along[k, 0] = -z
        along[k, 1] = z


@njit(nogil=True, cache=True)
def ba_edgelet_setup(cam, plane, poses, frames, mcam, medg, lines, iters, tol, offset_px):
    """An adjustment's start in one call (``bundle_edgelets.EdgeletLM``; separately, the Python between the calls
    took as long as the kernels): the measured lines a + λb of ``lines`` = (a, b, sel), rows ``sel`` of a and b,
    moved to the normalised plane (``ba_edgelet_planes``: xy, g, to_px), each measurement's plane angle
    (``ba_edgelet_plane_angles``) and its sample points (``ba_edgelet_place`` in ``plane``, the unit pinhole's
    parameters), at ``poses`` and ``frames``."""
    line_a, line_b, sel = lines
    m = mcam.shape[0]
    xy = np.empty((m, 2))
    g = np.empty((m, 2))
    to_px = np.empty((m, 2, 2))
    ba_edgelet_planes(cam, line_a[sel], line_b[sel], iters, tol, xy, g, to_px)
    angle = np.empty(m)
    ba_edgelet_plane_angles(poses, frames, mcam, medg, angle)
    along = np.empty((m, 2))
    ba_edgelet_place(plane, poses, frames, mcam, medg, offset_px, to_px, along)
    return xy, g, to_px, angle, along


@njit(nogil=True, cache=True)
def ba_edgelet_rows(cam, poses, frames, meas, use, along, err, jp, je, e2, bad):
    """One linearisation's per-measurement terms at the sample points ``along`` (M, 2): for those in ``use``, the
    residuals ``err`` (M, 2) px, their Jacobian rows ``jp`` (M, 2, 6), ``je`` (M, 2, 4) (eq. 7–9,
    ``edgelet_ba_terms``), e2 = ε₁² + ε₂² and bad = a sample point behind the camera. ``meas`` = (mcam, medg,
    line_a, line_n)."""
    mcam, medg, line_a, line_n = meas
    J = np.empty((2, 3))
    for k in range(mcam.shape[0]):
        clear_residual(k, err, e2, bad)
        if not use[k]:
            continue
        T = poses[mcam[k]]
        E = frames[medg[k]]
        bad[k] = not measurement_rows(cam, T, E, along[k], line_a[k], line_n[k], J, jp[k], je[k], err[k])
        if bad[k]:
            continue
        e2[k] = err[k, 0] * err[k, 0] + err[k, 1] * err[k, 1]


@njit(nogil=True, cache=True)
def ba_edgelet_residuals(cam, poses, frames, meas, along, offset_px, to_px, use, err, e2, bad, placed):
    """Eq. 7 for the measurements in ``use``: ε_n = m̂·(s_n − a) (M, 2) px, e2 = ε₁² + ε₂², bad = a sample point
    behind the camera (as ``edgelet_ba_terms``, without the Jacobians); and ``placed`` (M, 2), the sample points
    of eq. 6 at this state for the next linearisation: |d| is the chord |s₂ − s₁| / (z₂ − z₁) of the two
    projections just made (the tangent ``_along`` takes at the centre, to second order in the image curvature of
    the projected edgelet). Where there are none (not in use, or bad), ``placed`` keeps ``along``."""
    mcam, medg, line_a, line_n = meas
    J = np.empty((2, 3))
    for k in range(mcam.shape[0]):
        clear_residual(k, err, e2, bad)
        z0 = along[k, 0]
        z1 = along[k, 1]
        placed[k, 0] = z0
        placed[k, 1] = z1
        if not use[k]:
            continue
        T = poses[mcam[k]]
        E = frames[medg[k]]
        cx, cy, cz, dx, dy, dz = axis_in_camera(T, E)
        if cz + z0 * dz <= 0.0 or cz + z1 * dz <= 0.0:
            bad[k] = True
            continue
        u0, v0, _ = project(cam, cx + z0 * dx, cy + z0 * dy, cz + z0 * dz)
        u1, v1, _ = project(cam, cx + z1 * dx, cy + z1 * dy, cz + z1 * dz)
        n0, n1, a0, a1 = line_n[k, 0], line_n[k, 1], line_a[k, 0], line_a[k, 1]
        err[k, 0] = n0 * (u0 - a0) + n1 * (v0 - a1)
        err[k, 1] = n0 * (u1 - a0) + n1 * (v1 - a1)
        e2[k] = err[k, 0] * err[k, 0] + err[k, 1] * err[k, 1]
        if z1 > z0:
            z = offset_px / max(_pixels(to_px[k], u1 - u0, v1 - v0) / (z1 - z0), 1e-12)
        else:  # never placed: the centre was outside the lens's range (``_along``)
            z = _along(cam, T, E, offset_px, to_px[k], J)
        placed[k, 0] = -z
        placed[k, 1] = z


@njit(nogil=True, cache=True)
def ba_edgelet_linearise(err, jp, je, e2, bad, use, c2, medg, mrow, U, ea, V, eb, A, B, live):
    """Add the Tukey-weighted edgelet terms to U, ε_a (free camera rows ``mrow``, −1 fixed) and set V, ε_b and the
    weighted rows A = √w·jp (M, 2, 6), B = √w·je (M, 2, 4) of the measurements that are ``live`` (out) in the
    system; W = AᵀB is never formed (``bundle_schur_kernels.ba_edgelet_schur``). ``err``, ``jp``, ``je``, ``e2``,
    ``bad`` from ``ba_edgelet_rows``. U is symmetric on entry and on return."""
    V[:] = 0.0
    eb[:] = 0.0
    for k in range(medg.shape[0]):
        live[k] = False
        if not use[k] or bad[k] or e2[k] >= c2:
            continue
        live[k] = True
        # Square root of the Tukey weight on the errors and the Jacobians, as for points (PTAM code).
        sw = 1.0 - e2[k] / c2
        _accumulate(jp[k], je[k], err[k], sw, medg[k], mrow[k], U, ea, V, eb, A[k], B[k])
    for e in range(V.shape[0]):
        for a in range(4):
            for b in range(a):
                V[e, b, a] = V[e, a, b]
    for r in range(U.shape[0]):  # the lower triangles were added
        for a in range(6):
            for b in range(a):
                U[r, b, a] = U[r, a, b]


@njit(nogil=True, cache=True)
def ba_edgelet_linearise_at(cam, poses, frames, meas, along, rows, terms, use, c2, mrow, normal, live):
    """One linearisation in one call: ``ba_edgelet_rows`` at this state (``rows``; False when they were taken for
    a pooled Tukey cut-off) and ``ba_edgelet_linearise``; returns the robust cost. ``terms`` = (err, jp, je, e2,
    bad), ``normal`` = (U, ε_a, V, ε_b, A, B)."""
    err, jp, je, e2, bad = terms
    U, ea, V, eb, A, B = normal
    if rows:
        ba_edgelet_rows(cam, poses, frames, meas, use, along, err, jp, je, e2, bad)
    ba_edgelet_linearise(err, jp, je, e2, bad, use, c2, meas[1], mrow, U, ea, V, eb, A, B, live)
    return ba_robust_cost(e2, bad, use, c2)


@njit(nogil=True, cache=True)
def ba_edgelet_trial(cam, poses, frames, de, meas, along, offset_px, to_px, live, out, c2):
    """A trial step in one call: the frames after the updates ``de`` (``frames_updated``), the residuals of the
    measurements ``live`` there at the linearisation's sample points ``along`` (``ba_edgelet_residuals``; ``out`` =
    (err, e2, bad, placed)) and their robust cost. Returns (frames, cost)."""
    err, e2, bad, placed = out
    F = np.empty_like(frames)
    frames_updated(frames, de, F)
    ba_edgelet_residuals(cam, poses, F, meas, along, offset_px, to_px, live, err, e2, bad, placed)
    return F, ba_robust_cost(e2, bad, live, c2)


@njit(nogil=True, cache=True, inline="always")
def _accumulate(jp, je, err, sw, e, r, U, ea, V, eb, A, B):
    for s in range(2):
        res = -sw * err[s]
        for a in range(4):
            B[s, a] = sw * je[s, a]
        for a in range(4):
            for b in range(a + 1):
                V[e, a, b] += B[s, a] * B[s, b]
            eb[e, a] += B[s, a] * res
        if r < 0:
            continue
        for a in range(6):
            A[s, a] = sw * jp[s, a]
        for a in range(6):
            for b in range(a + 1):
                U[r, a, b] += A[s, a] * A[s, b]
            ea[r, a] += A[s, a] * res


@njit(nogil=True, cache=True)
def ba_edgelet_seen_update(jp, je, de, medg, use, bad, seen):
    """Σ over edgelets of the largest squared motion, in metres, that one of their measurements in ``use`` (and not
    ``bad``) sees of one of their sample points under the update ``de`` (E, 4): the change of its perpendicular
    distance, je·δμ_E px (eq. 9), over the pixels one metre of camera-frame motion moves it at most, |jp[:3]| (the
    translation part of eq. 8). ``seen`` (E,) is scratch (out: each edgelet's share)."""
    seen[:] = 0.0
    for k in range(medg.shape[0]):
        if not use[k] or bad[k]:
            continue
        e = medg[k]
        for s in range(2):
            d = je[k, s, 0] * de[e, 0] + je[k, s, 1] * de[e, 1] + je[k, s, 2] * de[e, 2] + je[k, s, 3] * de[e, 3]
            g2 = jp[k, s, 0] * jp[k, s, 0] + jp[k, s, 1] * jp[k, s, 1] + jp[k, s, 2] * jp[k, s, 2]
            if g2 > 0.0 and d * d > seen[e] * g2:
                seen[e] = d * d / g2
    return seen.sum()


@njit(nogil=True, cache=True)
def ba_edgelet_plane_angles(poses, frames, mcam, medg, angle):
    """Per measurement, the angle (radians, in (−π/2, π/2]) of the plane through its edgelet's 3-D line and its
    keyframe's centre, modulo π from the plane of the edgelet's first measurement (``angle`` (M,); NaN where the
    keyframe looks along the line and spans no plane). Every such plane contains the line, so its normal lies in
    the frame's x-y plane, and two planes meeting at a few degrees leave the line free to turn within them
    (Agility §4.3's aperture problem; ``ba_edgelet_hold``)."""
    ref = np.full(frames.shape[0], np.nan)
    for k in range(mcam.shape[0]):
        T = poses[mcam[k]]
        E = frames[medg[k]]
        cx, cy, cz = camera_centre(T)
        r0 = E[0, 3] - cx  # n = (centre − camera centre) × direction
        r1 = E[1, 3] - cy
        r2 = E[2, 3] - cz
        n0 = r1 * E[2, 2] - r2 * E[1, 2]
        n1 = r2 * E[0, 2] - r0 * E[2, 2]
        n2 = r0 * E[1, 2] - r1 * E[0, 2]
        x = n0 * E[0, 0] + n1 * E[1, 0] + n2 * E[2, 0]
        y = n0 * E[0, 1] + n1 * E[1, 1] + n2 * E[2, 1]
        angle[k] = np.nan
        if x == 0.0 and y == 0.0:
            continue
        phi = math.atan2(y, x)
        e = medg[k]
        if np.isnan(ref[e]):
            ref[e] = phi
        d = (phi - ref[e]) % math.pi
        angle[k] = d - math.pi if d > 0.5 * math.pi else d


@njit(nogil=True, cache=True)
def ba_edgelet_hold(medg, use, angle, min_angle, frames, start_frames):
    """Hold the edgelets whose measurements in ``use`` are fewer than two, or whose planes (``angle``, from
    ``ba_edgelet_plane_angles``) span less than ``min_angle``: their measurements leave ``use``, and those that had
    one in it go back to ``start_frames``. Returns the measurements left in use. The span is the shortest arc
    (modulo π) holding their angles, the widest pair's angle when under π/2: the largest minus the smallest angle
    read in (−π/2, π/2] and again in [0, π), whichever is less (an arc under π/2 cannot hold both reads' wraps,
    π/2 apart)."""
    ne = frames.shape[0]
    count = np.zeros(ne, np.int64)
    lo = np.full((ne, 2), np.inf)
    hi = np.full((ne, 2), -np.inf)
    for k in range(medg.shape[0]):
        if use[k]:
            e = medg[k]
            count[e] += 1
            a = angle[k]
            if not np.isnan(a):
                b = a + math.pi if a < 0.0 else a
                lo[e, 0] = min(lo[e, 0], a)
                hi[e, 0] = max(hi[e, 0], a)
                lo[e, 1] = min(lo[e, 1], b)
                hi[e, 1] = max(hi[e, 1], b)
    held = np.zeros(ne, np.bool_)
    for e in range(ne):
        span = min(hi[e, 0] - lo[e, 0], hi[e, 1] - lo[e, 1])
        if count[e] > 0 and (count[e] < 2 or not span >= min_angle):
            held[e] = True
            frames[e] = start_frames[e]
    n = 0
    for k in range(medg.shape[0]):
        if use[k] and held[medg[k]]:
            use[k] = False
        n += use[k]
    return n
