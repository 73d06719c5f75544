"""PTAM's PatchFinder, batched: warped template, zero-mean SSD at FAST corners, sub-pixel refinement (PTAM §5.3).

One call handles a whole set of patches with one kernel call per step (``ptam.patch.template_kernels``,
``patch_search``, ``patch_subpix``). Positions cross between level 0 and the search level with
x_L = (x_0 + 0.5)/2^L − 0.5; the search centre is the prediction rounded at the search level and the radius
is rounded up there (PTAM code ``FindPatchCoarse``: ``(range + scale − 1) / scale``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .search_kernels import search_patches
from .subpix_kernels import refine_subpix
from .template_kernels import make_templates


@dataclass(frozen=True)
class PatchMatches:
    """Per patch: ``attempted`` (its template could be made: PTAM counts only these), ``found``, the match
    ``xy`` at level 0 (valid where found) and ``subpix`` (the position was refined). ``unconverged``: matched,
    but the refinement did not converge, so the match was dropped; its ``xy`` is the integer match."""

    attempted: np.ndarray
    found: np.ndarray
    xy: np.ndarray
    subpix: np.ndarray
    unconverged: np.ndarray


def frozen(arrays) -> tuple:
    """A tuple of read-only C-contiguous views, so numba sees one homogeneous tuple type."""
    out = []
    for a in arrays:
        v = np.ascontiguousarray(a).view()
        v.setflags(write=False)
        out.append(v)
    return tuple(out)


class PatchFinder:
    def __init__(self, patch_cfg):
        self.cfg = patch_cfg
        self.max_ssd = float(patch_cfg.max_ssd_per_pixel) * patch_cfg.size * patch_cfg.size
        self.flat_fraction = float(patch_cfg.max_ssd_template_fraction)

    def find(
        self,
        pyramid,
        kf_images,
        source_kf,
        source_level,
        source_xy,
        M,
        level,
        predicted_xy,
        radius_px,
        subpix,
        require_converged: bool = True,
    ) -> PatchMatches:
        """Search patches (source keyframe/level/pixel, template matrix M (n, 2, 2), search ``level`` (n,))
        around level-0 predictions (n, 2) within ``radius_px`` level-0 pixels; refine where ``subpix`` (n,).
        ``require_converged``: a refinement that does not converge loses the match (PTAM code's tracker); else
        the last iterate is kept (PTAM code's ``ReFind_Common``)."""
        n = len(level)
        cfg = self.cfg
        found, did_subpix, unconverged = (np.zeros(n, dtype=bool) for _ in range(3))
        xy = np.zeros((n, 2))
        if n == 0:
            return PatchMatches(found.copy(), found, xy, did_subpix, unconverged)
        templates, attempted = make_templates(
            frozen(kf_images),
            source_kf.astype(np.int32),
            source_level.astype(np.int8),
            np.ascontiguousarray(source_xy),
            np.ascontiguousarray(M),
            cfg.size,
        )
        ok = np.flatnonzero(attempted)
        lvl = level[ok].astype(np.int32)
        scale = np.exp2(lvl.astype(np.float64))
        center = np.rint((predicted_xy[ok] + 0.5) / scale[:, None] - 0.5).astype(np.int32)
        radius = np.ceil(radius_px / scale - 1e-9).astype(np.int32)
        levels, corners, luts = frozen(pyramid.levels), frozen(pyramid.corners), frozen(pyramid.row_lut)
        best, _, hit = search_patches(
            levels, corners, luts, templates[ok], lvl, center, radius, self.max_ssd, self.flat_fraction
        )
        pos = best.astype(np.float64)
        refine = np.flatnonzero(hit & subpix[ok])
        if len(refine):
            converged = self._refine(levels, templates[ok[refine]], lvl[refine], pos, refine, require_converged)
            if require_converged:
                hit[refine] = converged
                unconverged[ok[refine]] = ~converged
            did_subpix[ok[refine]] = converged
        found[ok] = hit
        xy[ok] = (pos + 0.5) * scale[:, None] - 0.5
        return PatchMatches(attempted, found, xy, did_subpix, unconverged)

    def _refine(self, levels, templates, lvl, pos, refine, require_converged: bool) -> np.ndarray:
        """Sub-pixel refinement of the matches ``pos[refine]`` in place; a refinement that did not converge
        leaves its integer match when ``require_converged``. Returns which converged."""
        pos_r, converged = refine_subpix(
            levels, templates, lvl, pos[refine], int(self.cfg.subpix_iterations), float(self.cfg.subpix_converge_px)
        )
        if require_converged:
            pos_r[~converged] = pos[refine[~converged]]
        pos[refine] = pos_r
        return converged
