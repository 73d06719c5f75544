"""Textured rectangles in 3-D, the only primitive of the synthetic scenes.

A rectangle is given either by its four ``corners`` in order (the texture's first row runs from corner 0
to corner 1, its first column from corner 0 to corner 3), or by ``center``, two perpendicular ``axes``
(the texture's row and column directions) and ``size`` (metres along each axis).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

_RIGHT_ANGLE_TOL = 1e-6  # |cos| between the two edges, and corner-closure error relative to the size


@dataclass(frozen=True)
class Rectangle:
    name: str
    origin: np.ndarray  # corner 0 (3,)
    axis_a: np.ndarray  # unit vector along the texture rows (3,)
    axis_b: np.ndarray  # unit vector along the texture columns (3,)
    size: tuple[float, float]  # metres along axis_a and axis_b
    texture: dict

    @property
    def normal(self) -> np.ndarray:
        return np.cross(self.axis_a, self.axis_b)

    def corners(self) -> np.ndarray:
        a, b = self.axis_a * self.size[0], self.axis_b * self.size[1]
        return np.stack([self.origin, self.origin + a, self.origin + a + b, self.origin + b])

    def packed(self) -> np.ndarray:
        """The kernel layout: origin, axis_a, axis_b, normal, size_a, size_b (14,)."""
        return np.concatenate([self.origin, self.axis_a, self.axis_b, self.normal, self.size])


def _vec(v, where, key, n=3):
    a = np.asarray(v, dtype=np.float64) if isinstance(v, (list, tuple)) else None
    if a is None or a.shape != (n,) or not np.all(np.isfinite(a)):
        raise InputError(f"{where}: '{key}' must be a list of {n} numbers, got {v!r}")
    return a


def rectangle_from_spec(d: dict, where: str) -> Rectangle:
    if not isinstance(d, dict):
        raise InputError(f"{where}: a rectangle must be a mapping")
    name = str(d.get("name", where))
    if "texture" not in d:
        raise InputError(f"{where}: rectangle needs a 'texture'")
    unknown = set(d) - {"name", "texture", "corners", "center", "axes", "size"}
    if unknown:
        raise InputError(f"{where}: unknown rectangle key(s) {', '.join(sorted(unknown))}")
    if "corners" in d:
        return _from_corners(d, name, where)
    if {"center", "axes", "size"} <= set(d):
        return _from_centre(d, name, where)
    raise InputError(f"{where}: give either 'corners' or 'center', 'axes' and 'size'")


def _from_corners(d: dict, name: str, where: str) -> Rectangle:
    c = d["corners"]
    if not isinstance(c, (list, tuple)) or len(c) != 4:
        raise InputError(f"{where}: 'corners' must list four 3-D points")
    P = np.stack([_vec(p, where, "corners") for p in c])
    ea, eb = P[1] - P[0], P[3] - P[0]
    wa, wb = np.linalg.norm(ea), np.linalg.norm(eb)
    if min(wa, wb) <= 0:
        raise InputError(f"{where}: degenerate rectangle (repeated corners)")
    if abs(ea @ eb) > _RIGHT_ANGLE_TOL * wa * wb or np.linalg.norm(P[2] - (P[0] + ea + eb)) > _RIGHT_ANGLE_TOL * max(
        wa, wb
    ):
        raise InputError(f"{where}: the four corners are not a rectangle (list them in order round the edge)")
    return Rectangle(name, P[0], ea / wa, eb / wb, (float(wa), float(wb)), d["texture"])


def _from_centre(d: dict, name: str, where: str) -> Rectangle:
    c = _vec(d["center"], where, "center")
    ax = d["axes"]
    if not isinstance(ax, (list, tuple)) or len(ax) != 2:
        raise InputError(f"{where}: 'axes' must be two 3-D directions")
    ea, eb = (_vec(v, where, "axes") for v in ax)
    if min(np.linalg.norm(ea), np.linalg.norm(eb)) <= 0:
        raise InputError(f"{where}: 'axes' must be non-zero")
    ea, eb = ea / np.linalg.norm(ea), eb / np.linalg.norm(eb)
    if abs(ea @ eb) > _RIGHT_ANGLE_TOL:
        raise InputError(f"{where}: 'axes' must be perpendicular")
    size = _vec(d["size"], where, "size", 2)
    if np.any(size <= 0):
        raise InputError(f"{where}: 'size' must be positive")
    origin = c - 0.5 * size[0] * ea - 0.5 * size[1] * eb
    return Rectangle(name, origin, ea, eb, (float(size[0]), float(size[1])), d["texture"])
