"""Whole-image alignment of two small blurry images over SE(2), optionally with a mean intensity offset, by
efficient second-order minimisation (Benhimane & Malis; Agility §6, §7; PTAM code
``SmallBlurryImage::IteratePosRelToTarget``).

The warp maps a template pixel x to c + R(θ)(x − c) + t in the current image, c the image centre. Each
iteration resamples the current image through the warp (bilinear), and over the interior pixels whose warped
value and four neighbours all sampled inside the image accumulates the normal equations of the residual
r = I(w(x)) − T(x) + o with the ESM Jacobian: the mean of the warped image's and the template's central-difference
gradients, times the generators (1, 0), (0, 1), (−(y − c_y), x − c_x), and 1 for the offset. The solution u is
applied as w ← w ∘ (R(−u_θ), −u_t), o ← o − u_o. ``params`` is (t_x, t_y, θ, o); the score is the SSD of the last
iteration, before its update (PTAM code). An iteration whose normal equations are singular (a textureless
image) stops the minimisation. ``esm_se2_ref`` is the numpy reference.

``robust`` makes each iteration a step of iteratively reweighted least squares with Tukey's biweight, as PTAM's
pose update (§5.4) is: the pixels of something that moves on its own (Agility §9.3: "a hand moved rapidly before
the camera") disagree with the camera's motion by far more than the rest, beyond the cut-off that the median
residual sets, and drop out of the normal equations instead of dragging the alignment after them. The score is
still the plain SSD.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..geometry.cholesky_kernels import cholesky_solve
from ..geometry.tukey_kernels import tukey_sigma_sq, tukey_weight

_PIVOT_EPS = 1e-12  # relative to the largest diagonal entry: below this the system is singular


@njit(nogil=True, cache=True)
def _warp(image, out, valid, c, s, tx, ty, cx, cy):
    h, w = image.shape
    for y in range(h):
        for x in range(w):
            dx = x - cx
            dy = y - cy
            u = cx + c * dx - s * dy + tx
            v = cy + s * dx + c * dy + ty
            if u < 0.0 or v < 0.0 or u > w - 1.0 or v > h - 1.0:
                valid[y, x] = False
                out[y, x] = 0.0
                continue
            x0 = min(int(u), w - 2)
            y0 = min(int(v), h - 2)
            fx = u - x0
            fy = v - y0
            a = image[y0, x0] + fx * (image[y0, x0 + 1] - image[y0, x0])
            b = image[y0 + 1, x0] + fx * (image[y0 + 1, x0 + 1] - image[y0 + 1, x0])
            out[y, x] = a + fy * (b - a)
            valid[y, x] = True


@njit(nogil=True, cache=True)
def esm_se2(image, template, template_grad, params0, iterations, with_offset, robust):
    """Align ``image`` (H, W) float32 to ``template`` (H, W) float32, whose derivative ``template_grad``
    (H, W, 2) holds central differences (T[x+1] − T[x−1]) / 2, zero on the border. Starts from ``params0``
    (t_x, t_y, θ, o); ``with_offset`` also fits o; ``robust`` weights each pixel by Tukey's biweight of its
    residual, the cut-off from that iteration's median squared residual. Returns (params (4,), score,
    iterations run)."""
    h, w = image.shape
    cx = 0.5 * (w - 1)
    cy = 0.5 * (h - 1)
    p = params0.copy()
    warped = np.zeros((h, w), dtype=np.float32)
    valid = np.zeros((h, w), dtype=np.bool_)
    n = 4 if with_offset else 3
    score = 0.0
    done = 0
    A = np.zeros((4, 4))
    b = np.zeros(4)
    res = np.empty(h * w)
    jac = np.empty((h * w, 3))
    for _ in range(iterations):
        c = np.cos(p[2])
        s = np.sin(p[2])
        _warp(image, warped, valid, c, s, p[0], p[1], cx, cy)
        m = 0
        score = 0.0
        for y in range(1, h - 1):
            for x in range(1, w - 1):
                if not (valid[y, x] and valid[y, x - 1] and valid[y, x + 1] and valid[y - 1, x] and valid[y + 1, x]):
                    continue
                gx = 0.25 * (warped[y, x + 1] - warped[y, x - 1]) + 0.5 * template_grad[y, x, 0]
                gy = 0.25 * (warped[y + 1, x] - warped[y - 1, x]) + 0.5 * template_grad[y, x, 1]
                jac[m, 0] = gx
                jac[m, 1] = gy
                jac[m, 2] = -(y - cy) * gx + (x - cx) * gy
                r = warped[y, x] - template[y, x] + p[3]
                res[m] = r
                score += r * r
                m += 1
        c2 = tukey_sigma_sq(res[:m] * res[:m], 0.0) if robust else 0.0
        # The normal equations' distinct entries, accumulated in scalars (J = (gx, gy, gr, 1)).
        a00 = a10 = a11 = a20 = a21 = a22 = a30 = a31 = a32 = a33 = 0.0
        b0 = b1 = b2 = b3 = 0.0
        for k in range(m):
            gx, gy, gr, r = jac[k, 0], jac[k, 1], jac[k, 2], res[k]
            wt = tukey_weight(r * r, c2) if c2 > 0.0 else 1.0
            a00 += wt * gx * gx
            a10 += wt * gy * gx
            a11 += wt * gy * gy
            a20 += wt * gr * gx
            a21 += wt * gr * gy
            a22 += wt * gr * gr
            a30 += wt * gx
            a31 += wt * gy
            a32 += wt * gr
            a33 += wt
            b0 += wt * gx * r
            b1 += wt * gy * r
            b2 += wt * gr * r
            b3 += wt * r
        A[0, 0], A[1, 1], A[2, 2], A[3, 3] = a00, a11, a22, a33
        A[0, 1] = A[1, 0] = a10
        A[0, 2] = A[2, 0] = a20
        A[1, 2] = A[2, 1] = a21
        A[0, 3] = A[3, 0] = a30
        A[1, 3] = A[3, 1] = a31
        A[2, 3] = A[3, 2] = a32
        b[0], b[1], b[2], b[3] = b0, b1, b2, b3
        u, ok = cholesky_solve(A, b, n, _PIVOT_EPS)
        if not ok:
            break
        # w <- w o (R(-u_theta), -u_t): the template-side increment rotated into the current image.
        p[0] -= c * u[0] - s * u[1]
        p[1] -= s * u[0] + c * u[1]
        p[2] -= u[2]
        if with_offset:
            p[3] -= u[3]
        done += 1
    return p, score, done
