"""numpy reference for ``ptam.mapping.edgelet_epipolar_kernels.curve_hits`` (Agility §4.3): every sample of every
curve as numpy arrays, hits looked up at once, runs found by their starts."""

from __future__ import annotations

import numpy as np

from ptam.edgelet.edgelet import perp
from ptam.geometry import se3
from tests.reference.edgelet_triangulation import line_planes_ref


def _samples(length, step):
    """Row, piece and fraction of the points every ``step`` along each row's polyline of piece lengths (n, s)."""
    n, s = length.shape
    cum = np.cumsum(length, axis=1)
    rows, pieces, fracs = [], [], []
    for c in range(n):
        arc = np.arange(int(np.floor(cum[c, -1] / step)) + 1) * step
        j = np.clip(np.searchsorted(cum[c], arc, side="right"), 0, s - 1)
        before = np.where(j > 0, cum[c, np.maximum(j - 1, 0)], 0.0)
        frac = (arc - before) / np.maximum(length[c, j], np.finfo(float).tiny)
        rows.append(np.full(len(arc), c))
        pieces.append(j)
        fracs.append(np.clip(frac, 0.0, 1.0))
    return np.concatenate(rows), np.concatenate(pieces), np.concatenate(fracs)


def _run_middles(cand, hit):
    prev = np.concatenate([[False], hit[:-1] & (cand[1:] == cand[:-1])])
    start = np.flatnonzero(hit & ~prev)
    nxt = np.concatenate([hit[1:] & (cand[1:] == cand[:-1]), [False]])
    end = np.flatnonzero(hit & ~nxt)
    return (start + end) // 2


def curve_hits_ref(uv, seg_ok, length, inv_z, step, edgels, border):
    cand, j, frac = _samples(length, step)
    seg = np.diff(uv, axis=1)
    pts = uv[cand, j] + frac[:, None] * seg[cand, j]
    h, w = edgels.shape
    with np.errstate(invalid="ignore"):
        inside = (pts[:, 0] >= border) & (pts[:, 1] >= border) & (pts[:, 0] <= w - 1 - border)
        inside &= pts[:, 1] <= h - 1 - border
    hit = seg_ok[cand, j] & inside
    ix = np.rint(np.where(hit[:, None], pts, 0.0)).astype(np.int64)
    hit &= edgels[ix[:, 1], ix[:, 0]] > 0
    mid = _run_middles(cand, hit)
    iz = inv_z[j] + frac * (inv_z[j + 1] - inv_z[j])
    tangent = seg[cand, j] / np.maximum(np.linalg.norm(seg[cand, j], axis=1), np.finfo(float).tiny)[:, None]
    return cand[mid], pts[mid], iz[mid], tangent[mid]


def polarity_cull_ref(camera, T_k, T_t, a, b, z, g, tangent, min_deg):
    """§4.3 step 4 for matches at depth ``z`` along source lines (a, b) of keyframe k, with target gradients ``g``
    and curve tangents ``tangent``: which to keep."""
    gn = np.linalg.norm(g, axis=1)
    g_hat = g / np.maximum(gn, np.finfo(float).tiny)[:, None]
    crossing = np.abs(np.sum(g_hat * tangent, axis=1)) >= np.sin(np.deg2rad(min_deg))
    plane, _ = line_planes_ref(camera, T_k, a, b)
    ray = np.concatenate([camera.unproject(a), np.ones((len(a), 1))], axis=1)
    Xk = ray * z[:, None]
    light = np.einsum("nij,nj->ni", camera.project_jacobian(Xk), plane @ T_k[:3, :3].T)
    side = np.sign(np.sum(light * perp(b), axis=1))
    Xt = se3.transform(T_t, se3.transform(se3.inv(T_k), Xk))
    with np.errstate(divide="ignore", invalid="ignore"):
        J_t = camera.project_jacobian(Xt)
    light_t = np.einsum("nij,nj->ni", J_t, (plane @ T_t[:3, :3].T) * side[:, None])
    return (gn > 0) & crossing & (np.sum(light_t * g, axis=1) > 0) & (Xt[:, 2] > 0)


def curve_vertices_ref(camera, T_ts, ray, z, max_len):
    n, v = len(ray), len(z)
    Xt = (ray[:, None, :] * z[None, :, None]) @ T_ts[:3, :3].T + T_ts[:3, 3]
    front = camera.valid(Xt.reshape(-1, 3)).reshape(n, v)
    uv = camera.project(np.where(front[..., None], Xt, 1.0).reshape(-1, 3)).reshape(n, v, 2)
    length = np.linalg.norm(np.diff(uv, axis=1), axis=2)
    seg_ok = front[:, 1:] & front[:, :-1] & np.isfinite(length)
    return uv, seg_ok, np.where(seg_ok, np.minimum(length, max_len), 0.0)
