"""Edgelets in the frame-rate tracker (Agility §5, §8).

Each frame, after the points' fine search: the map's edgelets measured in the keyframe nearest to the pose
(§5.2's table is per keyframe; an edgelet that keyframe did not measure counts as occluded from there) are
projected with the pose so far; each one's edge-normal blur is l = |J γ_C| (eq. 10) with J its 1×6 Jacobian
(eq. 11) and γ_C the motion during the exposure; the visibility table gives, for that blur, whether it can be
seen and its r_search and t_min; the visible ones in the image get one blur-matched sawtooth search along
their predicted normal (§5.1). γ_C is the motion during the exposure (``MotionModel.exposure_motion`` with
``tracker.exposure_fraction``).

Agility §8: edgelets whose search range is 20 px or more (``coarse_min_range_px``) join the coarse stage, measured
from the prior and used with the coarse points in its pose update; the fine stage then measures every visible
edgelet again from the updated pose (the coarse measurements served only to get there).

A found edgelet is a perpendicular-distance measurement: the edge lies on the line through c + ε n̂ with
normal n̂ (c, n̂ as predicted). The final pose uses points and edgelets in one Tukey IRLS
(``pose_kernels.pose_irls_edgelets``); an edgelet's σ is ``track_sigma_px`` level-0 pixels (Agility §8: single-
pixel variance for points and edgelets alike), so its scaled error is on the scale of a level-0 point's.

Model selection (Gauglitz et al. §4.2): a frame that finds at least ``track_min_found`` edgelets sees mapped 3-D
structure, so its pose is [R|t] from points and edgelets; otherwise the tracker's usual choice runs on points
alone, unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera.model import CameraModel
from ..config import Config
from ..edgelet import (
    Edgelets,
    VisibilityTable,
    blur_lengths,
    project_edgelets_with_jacobian,
    search_edgelets,
    table_blurs,
)
from ..map.snapshot import MapSnapshot
from .pose_kernels import pose_irls_edgelets


@dataclass(frozen=True)
class EdgeletFrame:
    """One frame's edgelet searches: snapshot edgelet ``ids``, world ``centre`` (n, 3), the point ``xy``
    (n, 2) on the found edge (the predicted centre where the search failed), the predicted unit ``normal`` (n, 2)
    searched along, expected ``blur`` (px) and ``found``; ``weights`` (n,) their final Tukey weights (0 where not
    used)."""

    ids: np.ndarray
    centre: np.ndarray
    xy: np.ndarray
    normal: np.ndarray
    blur: np.ndarray
    found: np.ndarray
    weights: np.ndarray

    @staticmethod
    def empty() -> EdgeletFrame:
        z2 = np.zeros((0, 2))
        return EdgeletFrame(
            np.zeros(0, np.int64), np.zeros((0, 3)), z2, z2, np.zeros(0), np.zeros(0, bool), np.zeros(0)
        )

    @property
    def n_attempted(self) -> int:
        return len(self.ids)

    @property
    def n_found(self) -> int:
        return int(self.found.sum())


class EdgeletTracker:
    def __init__(self, camera: CameraModel, cfg: Config):
        self.camera = camera
        self.cfg = cfg
        self.ecfg = cfg.edgelets
        self._cam = camera.kernel_params()
        self._blurs = table_blurs(cfg.edgelets).astype(np.float64)

    def search(
        self, image: np.ndarray, snapshot: MapSnapshot | None, T_cw: np.ndarray, gamma: np.ndarray, coarse: bool = False
    ) -> EdgeletFrame:
        """§5.1–§5.2 for the visible edgelets of ``snapshot`` in the full-size ``image`` at pose ``T_cw``;
        ``gamma``: γ_C, the camera's motion during the exposure (eq. 10, the tracker's); ``coarse``: only those
        with a search range of at least ``coarse_min_range_px`` (§8)."""
        if not self.ecfg.enabled or snapshot is None or not snapshot.edgelet_tables:
            return EdgeletFrame.empty()
        ids, table = self._table(snapshot, T_cw)
        ed = Edgelets(snapshot.edgelet_centre[ids], snapshot.edgelet_direction[ids], snapshot.edgelet_normal[ids])
        p, jacobian = project_edgelets_with_jacobian(self.camera, T_cw, ed)
        blur = blur_lengths(jacobian, gamma)
        visible, radius, t_min = table.lookup(blur)
        h, w = image.shape
        inside = (p.centre[:, 0] >= 0) & (p.centre[:, 1] >= 0) & (p.centre[:, 0] <= w - 1) & (p.centre[:, 1] <= h - 1)
        wide = radius >= self.ecfg.coarse_min_range_px if coarse else True
        sel = np.flatnonzero(visible & p.valid & inside & wide)
        c, n = p.centre[sel], p.normal[sel]
        res = search_edgelets(image, c, n, blur[sel], radius[sel], t_min[sel], self.ecfg)
        xy = c + np.where(res.found, res.offset, 0.0)[:, None] * n
        return EdgeletFrame(ids[sel], ed.centre[sel], xy, n, blur[sel], res.found, np.zeros(len(sel)))

    def _table(self, snapshot: MapSnapshot, T_cw: np.ndarray) -> tuple[np.ndarray, VisibilityTable]:
        """The good edgelets of the nearest keyframe (by camera centre) that has a visibility table, and it."""
        k, _ = snapshot.nearest_keyframe(T_cw, np.fromiter(snapshot.edgelet_tables, np.int64))
        ids, visible, r_search, t_min, max_blur = snapshot.edgelet_tables[k]
        good = ~snapshot.edgelet_bad[ids]
        return ids[good], VisibilityTable(self._blurs, visible[good], r_search[good], t_min[good], max_blur[good])

    def usable(self, frame: EdgeletFrame) -> bool:
        """Enough edgelets were found for the joint [R|t] update (see the module docstring)."""
        return frame.n_found >= self.ecfg.track_min_found

    def final_pose(self, T_cw, X, Xw, xy, level, smear, fixed_sigma: bool, frame: EdgeletFrame, coarse: bool = False):
        """A pose from points (X, Xw homogeneous, found at ``xy`` on ``level``, with smear axes ``smear``,
        ``patch_blur.smear_axes``) and the found edgelets: the fine stage's final one, or with ``coarse`` the coarse
        stage's (re-linearised every iteration, the coarse Tukey override, as ``update_pose``): (T_cw, point
        weights, the frame with its edgelet weights)."""
        tcfg = self.cfg.tracker
        sigma_sq = tcfg.tukey_override_sigma_sq_coarse if coarse else tcfg.tukey_override_sigma_sq_fine
        override = sigma_sq if tcfg.tukey_override_enabled and fixed_sigma else 0.0
        f = frame.found
        T, w, ew = pose_irls_edgelets(
            self._cam,
            np.ascontiguousarray(T_cw, dtype=np.float64),
            np.ascontiguousarray(X, dtype=np.float64),
            np.ascontiguousarray(Xw, dtype=np.float64),
            np.ascontiguousarray(xy, dtype=np.float64),
            np.exp2(-np.asarray(level, dtype=np.float64)),
            np.ascontiguousarray(smear, dtype=np.float64),
            np.ascontiguousarray(frame.centre[f]),
            np.ascontiguousarray(frame.xy[f]),
            np.ascontiguousarray(frame.normal[f]),
            np.full(int(f.sum()), 1.0 / self.ecfg.track_sigma_px),
            int(tcfg.irls_iterations),
            1 if coarse else int(tcfg.relinearise_every),
            float(tcfg.min_tukey_sigma),
            float(tcfg.pose_prior),
            int(tcfg.tukey_override_after),
            float(override),
            np.zeros(3),
            -1.0,
        )
        weights = np.zeros(frame.n_attempted)
        weights[f] = ew
        return T, w, EdgeletFrame(frame.ids, frame.centre, frame.xy, frame.normal, frame.blur, frame.found, weights)
