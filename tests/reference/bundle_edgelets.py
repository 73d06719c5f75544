"""numpy references for ``ptam.mapping.bundle_edgelet_kernels`` (Agility §4.4): plain numpy, dense matrices."""

from __future__ import annotations

import numpy as np

from ptam.edgelet import perp


def lens_linearised_ref(camera, a, b):
    """The unprojected points a, the normals g = m̂ᵀL of the lines along b and L, the lens's pixel Jacobian."""
    m_hat = perp(b / np.linalg.norm(b, axis=1, keepdims=True))
    xy = camera.unproject(a)
    to_px = camera.distort_jacobian(xy) * np.array([camera.fx, camera.fy])[None, :, None]
    return xy, np.einsum("mi,mij->mj", m_hat, to_px), to_px


def ba_edgelet_linearise_ref(err, Jp, Je, e2, bad, use, c2, mrow, medg, n_free, n_edgelets):
    """The edgelets' U, ε_a, V, ε_b, W (zero where not live or the camera is fixed) and live."""
    live = use & ~bad & (e2 < c2)
    sw = np.where(live, 1.0 - e2 / c2, 0.0)[:, None, None]
    A, B = Jp * sw, Je * sw
    r = -err * sw[:, :, 0]
    free = live & (mrow >= 0)
    U = np.zeros((n_free, 6, 6))
    ea = np.zeros((n_free, 6))
    np.add.at(U, mrow[free], np.einsum("ksa,ksb->kab", A[free], A[free]))
    np.add.at(ea, mrow[free], np.einsum("ksa,ks->ka", A[free], r[free]))
    V = np.zeros((n_edgelets, 4, 4))
    eb = np.zeros((n_edgelets, 4))
    np.add.at(V, medg[live], np.einsum("ksa,ksb->kab", B[live], B[live]))
    np.add.at(eb, medg[live], np.einsum("ksa,ks->ka", B[live], r[live]))
    W = np.zeros((len(err), 6, 4))
    W[free] = np.einsum("ksa,ksb->kab", A[free], B[free])
    return U, ea, V, eb, W, live


def ba_edgelet_schur_ref(V, eb, W, live, lam, mrow, medg, n_free):
    """The edgelets' −W V*⁻¹ Wᵀ (6N × 6N), −W V*⁻¹ ε_b and V*⁻¹, V* = V with its diagonal × (1 + λ)."""
    n = len(V)
    Vstar = V.copy()
    Vstar[:, np.arange(4), np.arange(4)] *= 1.0 + lam
    Vinv = np.zeros_like(V)
    for e in range(n):
        if np.all(np.linalg.eigvalsh(Vstar[e]) > 0):
            Vinv[e] = np.linalg.inv(Vstar[e])
    Wbig = np.zeros((6 * n_free, 4 * n))
    for k in np.flatnonzero(live & (mrow >= 0)):
        Wbig[6 * mrow[k] : 6 * mrow[k] + 6, 4 * medg[k] : 4 * medg[k] + 4] += W[k]
    Vbig = np.zeros((4 * n, 4 * n))
    for e in range(n):
        Vbig[4 * e : 4 * e + 4, 4 * e : 4 * e + 4] = Vinv[e]
    return -Wbig @ Vbig @ Wbig.T, -Wbig @ Vbig @ eb.ravel(), Vinv


def ba_edgelet_backsub_ref(Vinv, eb, W, live, mrow, medg, dcam):
    v = eb.copy()
    k = np.flatnonzero(live & (mrow >= 0))
    np.add.at(v, medg[k], -np.einsum("kab,ka->kb", W[k], dcam.reshape(-1, 6)[mrow[k]]))
    return np.einsum("eab,eb->ea", Vinv, v)


def ba_edgelet_seen_update_ref(jp, je, de, medg, use, bad, n_edgelets):
    """Each edgelet's largest squared sample-point motion seen by a measurement: (je·δμ_E / |jp[:3]|)² in m²."""
    ok = use & ~bad
    m2 = (np.einsum("ksa,ka->ks", je, de[medg]) ** 2 / np.sum(jp[:, :, :3] ** 2, axis=2))[ok].max(axis=1)
    seen = np.zeros(n_edgelets)
    np.maximum.at(seen, medg[ok], m2)
    return seen


def ba_edgelet_plane_spread_ref(poses, frames, mcam, medg, use, n_edgelets):
    """Widest angle (radians) between any two planes through an edgelet's line and its measuring keyframes'
    centres (lines' normals compared modulo π), by every pair; 0 with fewer than two."""
    spread = np.zeros(n_edgelets)
    C = -np.einsum("nji,nj->ni", poses[:, :3, :3], poses[:, :3, 3])
    for e in range(n_edgelets):
        k = np.flatnonzero(use & (medg == e))
        n = np.cross(frames[e, :3, 3] - C[mcam[k]], frames[e, :3, 2])
        keep = np.linalg.norm(n, axis=1) > 0
        n = n[keep] / np.linalg.norm(n[keep], axis=1, keepdims=True)
        if len(n) >= 2:
            spread[e] = np.arccos(np.clip(np.abs(n @ n.T), 0.0, 1.0)).max()
    return spread


def ba_edgelet_hold_ref(poses, frames, mcam, medg, use, min_angle, start_frames):
    """(use, frames) after holding the edgelets with fewer than two measurements in ``use`` or planes spanning less
    than ``min_angle`` (``ba_edgelet_plane_spread_ref``); held ones that had a measurement in use get their start."""
    n = len(frames)
    count = np.bincount(medg[use], minlength=n)
    held = (count > 0) & ((count < 2) | (ba_edgelet_plane_spread_ref(poses, frames, mcam, medg, use, n) < min_angle))
    frames = frames.copy()
    frames[held] = start_frames[held]
    return use & ~held[medg], frames
