"""Model-free estimation where no SfM group is in view (Gauglitz et al. TVCG 2013 §4.2, §6).

With enough found 3-D points the tracker's own model selection tells [R|t] from [R|0]. With rays alone (a
panorama, before the first map or after a pan into unmapped space) [R|t] cannot be estimated: the rotation-only
pose follows a sideways move by a mimicking rotation, and on a planar view that fits the rays to first order. So
the rays found in the frame are compared with where their keyframe saw them: E and H against a rotation by GRIC,
a translating winner measured against the rotation model's t_max
(:func:`~ptam.mapping.two_view.rotation_explains`). As any other evidence about a pose, a translation counts
once seen in ``reloc.confirm_frames`` checked frames in a row: one frame's homography can take a hand's jitter at
the end of a pan for one.
"""

from __future__ import annotations

import numpy as np

from ..camera.model import CameraModel
from ..config import Config
from ..mapping.two_view import rotation_explains
from ..tracking.track_result import TrackResult


def rays_translate(camera: CameraModel, cfg: Config, res: TrackResult, snap) -> bool:
    """Whether the rays found in frame ``res`` show a translation beyond the rotation-only model's t_max against
    one keyframe (every keyframe of a panorama group shares its centre), the keyframe's own measurements of them
    against the frame's (at most ``model_selection.rotation_check_max_matches``). Only the pose's Tukey inliers
    count: with every match found, desk_sweep's pure pan showed a translation in 3 frames in a row."""
    m = res.measurements
    use = m.found & m.inlier  # a mismatch costs E half what it costs H or a rotation (GRIC's cap, r − d = 1 vs 2)
    ids = m.point_ids[use]
    ray = snap.ray[ids]
    if not ray.any():
        return False
    ids, xy1 = ids[ray], m.xy[use][ray]
    at = np.full(len(snap.ray), -1, np.int64)
    at[ids] = np.arange(len(ids))
    rows = np.flatnonzero(at[snap.meas_pt] >= 0)  # the keyframes' measurements of the rays found
    kf = snap.meas_kf[rows]
    rows = rows[kf == _nearest_view(kf, res.T_cw, snap.kf_T_cw, cfg.init.min_matches)]
    cap = cfg.model_selection.rotation_check_max_matches
    if len(rows) > cap:  # evenly over the measurements, deterministic
        rows = rows[np.linspace(0, len(rows) - 1, cap).astype(np.int64)]
    xy0, xy1 = snap.meas_xy[rows], xy1[at[snap.meas_pt[rows]]]
    t_max_rel = cfg.tracker.fine_radius_px / camera.fx  # §6.2: t_max = α_max·depth, α_max = r_fine / f
    method = cfg.model_selection.rotation_check_method
    return not rotation_explains(camera, xy0, xy1, cfg.init, cfg.model_selection, method, t_max_rel)


def _nearest_view(kf: np.ndarray, T_cw: np.ndarray, kf_T_cw: np.ndarray, min_matches: int) -> int:
    """Of the keyframes ``kf`` (one per measurement of a found ray), the one whose optical axis is nearest the
    frame's among those that measured ``min_matches`` of the rays (else the one that measured most): Gauglitz
    §4.2 compares with the newest keyframe. A patch matched across a wide turn is warped as if its surface
    faced its source keyframe (a ray has no normal), and its match drifts by pixels: in desk_pan's realtime runs,
    against the keyframe that was the source of most rays, 24 frames back, a rotation left 2.9 px median
    residual and a translation showed three frames in a row (the track lost in 1 run of 6); against the
    newest keyframe, 0.5 px."""
    count = np.bincount(kf)
    ok = np.flatnonzero(count >= min_matches)
    if len(ok) == 0:
        return int(count.argmax())
    cos = kf_T_cw[ok, 2, :3] @ T_cw[2, :3]  # cosine between the optical axes (third rows of R_cw)
    return int(ok[np.argmax(cos)])


class RayCheck:
    """The check on a map's frames that see rays but too few 3-D points for [R|t] (``model_selection
    .min_sfm_points`` inliers): frames in a row that showed a translation."""

    def __init__(self, camera: CameraModel, cfg: Config):
        self.camera = camera
        self.cfg = cfg
        self._seen = 0

    @property
    def doubting(self) -> bool:
        """The newest frame showed a translation not yet confirmed: no keyframe from it."""
        return self._seen > 0

    def _rays_only(self, res: TrackResult, snap) -> bool:
        m = res.measurements
        ids = m.point_ids[m.found & m.inlier]
        ms = self.cfg.model_selection
        return ms.enabled and res.tracked and bool(np.count_nonzero(~snap.ray[ids]) < ms.min_sfm_points)

    def refutes(self, res: TrackResult, snap) -> bool:
        """Whether a frame tracked from a relocalised pose cannot confirm it: with rays alone in view only the
        rotation is measured, and the camera is assumed at the panorama's centre, where a camera that was lost
        by translating is not (desk_turn_walk in realtime: confirmed 5 cm off with σ 2 px, R preferred by GRIC,
        then 40 frames reported 20-190 mm off)."""
        return self._rays_only(res, snap)

    def translated(self, res: TrackResult, snap) -> bool:
        """Whether this frame confirms a translation the rays cannot follow (then the count starts over: the
        track it was seen in is lost)."""
        if not self._rays_only(res, snap):
            self._seen = 0
            return False
        self._seen = self._seen + 1 if rays_translate(self.camera, self.cfg, res, snap) else 0
        if self._seen < self.cfg.reloc.confirm_frames:
            return False
        self._seen = 0
        return True
