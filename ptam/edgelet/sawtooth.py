"""Frame-rate edgelet search under motion blur and the per-keyframe visibility table (Agility §5.1–§5.2).

``search_edgelets`` performs §5.1's single perpendicular search per edgelet: the signal along the predicted
normal is cross-correlated with a sawtooth whose period is the expected edge-normal blur l = |Jγ| (eq. 10,
``edgelet_projection.blur_lengths``), only dark-to-light responses count, and the search radius and minimum
response are per edgelet (from the visibility table, or a caller's defaults). The result ε is the signed
offset of the edge from the predicted centre along the normal, in pixels.

``build_visibility_table`` is §5.2: for edgelets measured in a keyframe, simulate box blurs of odd lengths
(``table_blur_min_px`` … ``table_blur_max_px``) on the keyframe's edge-normal signal and record, per blur,
visibility, r_search and t_min. ``VisibilityTable.lookup`` reads the row for each edgelet's expected blur.
The loops are in ``sawtooth_kernels``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.edgelet_section import EdgeletConfig
from ..errors import InputError
from .sawtooth_kernels import sawtooth_search, visibility_table


@dataclass(frozen=True)
class SawtoothResult:
    """``offset`` (N,) px along the unit normal from the predicted centre, ``response`` (N,) grey levels,
    ``found`` (N,)."""

    offset: np.ndarray
    response: np.ndarray
    found: np.ndarray


@dataclass(frozen=True)
class VisibilityTable:
    """§5.2 for N edgelets in one keyframe: ``blurs`` (B,) px; ``visible``, ``r_search`` (px), ``t_min``
    (grey levels) each (N, B); ``max_blur`` (N,) the largest blur still measured (0: none)."""

    blurs: np.ndarray
    visible: np.ndarray
    r_search: np.ndarray
    t_min: np.ndarray
    max_blur: np.ndarray

    def lookup(self, blur: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(visible, r_search, t_min) per edgelet for expected blurs (N,): the row of the smallest tabulated blur
        at least as long (blurs shorter than the first row use it; longer than the last are invisible)."""
        blur = np.asarray(blur, dtype=np.float64)
        col = np.searchsorted(self.blurs, blur, side="left")
        inside = col < len(self.blurs)
        col = np.minimum(col, len(self.blurs) - 1)
        rows = np.arange(len(blur))
        return self.visible[rows, col] & inside, self.r_search[rows, col], self.t_min[rows, col]


def _check(name: str, v, n: int) -> np.ndarray:
    v = np.ascontiguousarray(v, dtype=np.float64)
    if v.shape != (n,):
        raise InputError(f"sawtooth search: {name} must have shape ({n},), got {v.shape}")
    return v


def search_edgelets(
    image: np.ndarray,
    centres: np.ndarray,
    normals: np.ndarray,
    blur: np.ndarray,
    radius: np.ndarray,
    t_min: np.ndarray,
    cfg: EdgeletConfig,
) -> SawtoothResult:
    """§5.1: one blur-matched sawtooth search per edgelet from its predicted centre along its dark-to-light
    normal; ``blur``, ``radius`` and ``t_min`` are per edgelet (N,)."""
    c = np.ascontiguousarray(centres, dtype=np.float64).reshape(-1, 2)
    n = np.ascontiguousarray(normals, dtype=np.float64).reshape(-1, 2)
    if len(n) != len(c) or image.ndim != 2:
        raise InputError("sawtooth search: centres and normals must both be (N, 2) and the image 2-D")
    # An unknown (non-finite) blur is taken as the longest; a radius that is not a finite non-negative number
    # skips the edgelet, and no search runs beyond the image's size.
    blur = np.nan_to_num(
        _check("blur", blur, len(c)), nan=cfg.sawtooth_max_length_px, posinf=cfg.sawtooth_max_length_px
    )
    radius = _check("radius", radius, len(c))
    radius = np.where(np.isfinite(radius) & (radius >= 0), np.minimum(radius, max(image.shape)), -1.0)
    out = sawtooth_search(
        image,
        c,
        n,
        np.ascontiguousarray(blur),
        np.ascontiguousarray(radius),
        _check("t_min", t_min, len(c)),
        float(cfg.sawtooth_min_length_px),
        float(cfg.sawtooth_max_length_px),
    )
    return SawtoothResult(*out)


def table_blurs(cfg: EdgeletConfig) -> np.ndarray:
    """The box-blur lengths of the visibility table (§5.2: odd lengths 3 … 65 px)."""
    return np.arange(cfg.table_blur_min_px, cfg.table_blur_max_px + 1, cfg.table_blur_step_px, dtype=np.int64)


def build_visibility_table(
    image: np.ndarray, centres: np.ndarray, normals: np.ndarray, cfg: EdgeletConfig
) -> VisibilityTable:
    """§5.2 for edgelets measured in a keyframe ``image`` at ``centres`` with dark-to-light ``normals`` (N, 2)."""
    c = np.ascontiguousarray(centres, dtype=np.float64).reshape(-1, 2)
    n = np.ascontiguousarray(normals, dtype=np.float64).reshape(-1, 2)
    blurs = table_blurs(cfg)
    if np.any(blurs % 2 == 0):
        raise InputError("visibility table: box blurs must have odd lengths (centred kernels)")
    vis, rs, tm, mb = visibility_table(
        image,
        c,
        n,
        blurs,
        int(cfg.table_max_search_px),
        float(cfg.table_centre_tolerance_px),
        float(cfg.table_tmin_fraction),
        float(cfg.table_rsearch_fraction),
        float(cfg.sawtooth_min_length_px),
        float(cfg.sawtooth_max_length_px),
    )
    return VisibilityTable(blurs.astype(np.float64), vis, rs, tm, mb)
