"""Kernels: §4.3's aperture test of new-edgelet candidates against keyframe centres (``edgelet_aperture``).

A candidate is a point X on its 3-D line and the line's direction D, in the source keyframe k's frame (k's centre
at the origin). Triangulating it with keyframe j intersects the planes through the line and each centre; they
meet at less than the triangulation's own gate (``edgelets.triangulate_min_plane_angle_deg``) when the baseline
runs nearly along the line: the aperture problem. ``aperture_free`` also asks whether j sees the candidate, inside
its image, as ``edgelet_mapping`` asks before it measures an edgelet in a keyframe. In numpy these were arrays of
every keyframe × candidate built by some twenty operations; the numpy reference is
``tests/reference/edgelet_aperture.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project


@njit(nogil=True, cache=True, inline="always")
def _problem(X, D, i, cx, cy, cz, min_sin):
    """Whether the planes through candidate i's line and the centres 0 and C = (cx, cy, cz) meet at less than
    the angle whose sine is ``min_sin``."""
    dx, dy, dz = D[i, 0], D[i, 1], D[i, 2]
    x, y, z = X[i, 0], X[i, 1], X[i, 2]
    kx, ky, kz = dy * z - dz * y, dz * x - dx * z, dx * y - dy * x  # D × X
    x, y, z = x - cx, y - cy, z - cz
    jx, jy, jz = dy * z - dz * y, dz * x - dx * z, dx * y - dy * x  # D × (X − C)
    sx, sy, sz = ky * jz - kz * jy, kz * jx - kx * jz, kx * jy - ky * jx
    sin = math.sqrt(sx * sx + sy * sy + sz * sz)
    norm = math.sqrt(kx * kx + ky * ky + kz * kz) * math.sqrt(jx * jx + jy * jy + jz * jz)
    return sin < min_sin * max(norm, np.finfo(np.float64).tiny)


@njit(nogil=True, cache=True)
def aperture_problem(X, D, C, min_sin):
    """(K, N): whether candidate n (``X``, ``D`` (N, 3)) meets the aperture problem with centre ``C[j]`` (K, 3)."""
    out = np.empty((C.shape[0], X.shape[0]), dtype=np.bool_)
    for j in range(C.shape[0]):
        for i in range(X.shape[0]):
            out[j, i] = _problem(X, D, i, C[j, 0], C[j, 1], C[j, 2], min_sin)
    return out


@njit(nogil=True, cache=True)
def aperture_free(cam, T_jk, C, X, D, min_sin, border, width, height):
    """(K, N): whether keyframe j (pose ``T_jk`` (K, 4, 4) relative to k, centre ``C[j]`` in k's frame) sees
    candidate n's point ``X[n]`` in front, within the lens's range and ``border`` px inside its ``width`` ×
    ``height`` image, free of the aperture problem."""
    out = np.zeros((C.shape[0], X.shape[0]), dtype=np.bool_)
    for j in range(C.shape[0]):
        T = T_jk[j]
        for i in range(X.shape[0]):
            x, y, z = X[i, 0], X[i, 1], X[i, 2]
            u, v, ok = project(
                cam,
                T[0, 0] * x + T[0, 1] * y + T[0, 2] * z + T[0, 3],
                T[1, 0] * x + T[1, 1] * y + T[1, 2] * z + T[1, 3],
                T[2, 0] * x + T[2, 1] * y + T[2, 2] * z + T[2, 3],
            )
            if not (ok and border <= u <= width - 1 - border and border <= v <= height - 1 - border):
                continue
            out[j, i] = not _problem(X, D, i, C[j, 0], C[j, 1], C[j, 2], min_sin)
    return out
