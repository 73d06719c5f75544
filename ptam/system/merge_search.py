"""Finding two tracks that saw the same part of the scene (Gauglitz et al. TVCG 2013 §5.3).

A keyframe k1 of the current track is compared with the keyframes of every other track by its small blurry image
(the relocaliser's descriptor, Agility §7); the best keyframe's pose, rotated by the image alignment, starts a
regular tracking step of k1's image against that track's map. The pair is accepted only as a relocalisation is
(``reloc.confirm_frames`` good passes with most patches Tukey inliers); a failed pair is never tried again (the
paper's blacklist), and no pair is tried twice against the same state of a track.

The two maps' scale (§4.3): features both tracks hold in k1 — the other track's points found by the tracking
step beside this track's points measured in k1 at the same pixel — and the median ratio of their distances to
k1's camera in the two frames. The ratios must agree (``tracks.merge_max_scale_spread``): a wrong merge is
prevented, not repaired.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..camera.model import CameraModel
from ..config import Config
from ..map.snapshot import MapSnapshot
from ..mapping.track_merge import Link, Similarity
from ..tracking.relocaliser import Relocaliser
from ..tracking.tracker import Tracker
from ..vocabulary import Quality


@dataclass(frozen=True)
class Overlap:
    """Track ``other`` maps into the current track by ``sim``, linked by ``link`` (features in keyframe k1)."""

    other: int
    sim: Similarity
    link: Link


class MergeSearch:
    """The mapper thread's search for overlapping tracks, with its own tracker and relocalisers (the tracker's
    thread has its own: neither shares state with the other)."""

    def __init__(self, camera: CameraModel, cfg: Config):
        self.camera = camera
        self.cfg = cfg
        self.tracker = Tracker(camera, cfg)
        self._relocalisers: dict[int, Relocaliser] = {}
        self._tried: set[tuple[int, int, int, int]] = set()  # (track, k1, other track, its keyframe count)

    def find(
        self, track: int, snap: MapSnapshot | None, others: list[tuple[int, MapSnapshot]]
    ) -> tuple[bool, Overlap | None]:
        """Try the next untried (keyframe, other track) pair: (whether a pair was tried, the overlap found)."""
        if snap is None:
            return False, None
        ids = {i for i, _ in others}
        for gone in set(self._relocalisers) - ids:
            del self._relocalisers[gone]
        for k1 in range(snap.n_keyframes - 1, -1, -1):  # the newest keyframes first: where the camera is now
            if snap.keyframes[k1].panorama:  # its features are rays: no distances for a scale
                continue
            for other, osnap in others:
                key = (track, k1, other, osnap.n_keyframes)
                if key in self._tried:
                    continue
                self._tried.add(key)
                return True, self._verify(snap, k1, other, osnap)
        return False, None

    def _verify(self, snap: MapSnapshot, k1: int, other: int, osnap: MapSnapshot) -> Overlap | None:
        c = self.cfg.reloc
        kf = snap.keyframes[k1]
        reloc = self._relocalisers.setdefault(other, Relocaliser(self.camera, self.cfg)).attempt(kf.pyramid, osnap)
        if reloc is None or not reloc.accepted:
            return None
        tracker = self.tracker
        tracker.reset()
        tracker.set_pose(reloc.T_cw, recovered=True)
        res = None
        for _ in range(c.confirm_frames):  # the relocaliser's confirmation, on the one image
            res = tracker.track(kf.pyramid.levels[0], osnap, kf.pyramid)
            if res.quality != Quality.GOOD or res.inlier_fraction <= c.confirm_inlier_fraction:
                return None
            tracker.set_pose(res.T_cw)
        assert res is not None
        m = res.measurements
        sel = m.found & m.inlier
        link = Link(k1, m.point_ids[sel], m.xy[sel], m.level[sel])
        s = self._scale(snap, k1, osnap, res.T_cw, link)
        if s is None:
            return None
        T_b, T_a = snap.kf_T_cw[k1], res.T_cw
        R = T_b[:3, :3].T @ T_a[:3, :3]
        t = T_b[:3, :3].T @ (s * T_a[:3, 3] - T_b[:3, 3])
        return Overlap(other, Similarity(R, t, s), link)

    def _scale(self, snap: MapSnapshot, k1: int, osnap: MapSnapshot, T_a: np.ndarray, link: Link) -> float | None:
        """Gauglitz §4.3: the median ratio of the common features' distances to k1 in the two frames (this track's
        over the other's); None when too few features are common or their ratios disagree."""
        tc = self.cfg.tracks
        a = ~osnap.ray[link.point_ids]
        xy_a, d_a = link.xy[a], _distances(T_a, osnap.X[link.point_ids[a]])
        mine = snap.meas_pt[snap.meas_kf == k1]
        b = ~snap.ray[mine] & ~snap.bad[mine]
        xy_b = snap.meas_xy[snap.meas_kf == k1][b]
        d_b = _distances(snap.kf_T_cw[k1], snap.X[mine[b]])
        if len(xy_a) == 0 or len(xy_b) == 0:
            return None
        dist, j = cKDTree(xy_b).query(xy_a, distance_upper_bound=tc.merge_common_radius_px)
        common = np.isfinite(dist)
        if common.sum() < tc.merge_min_common:
            return None
        log_ratio = np.log(d_b[j[common]] / d_a[common])
        median = float(np.median(log_ratio))
        if float(np.median(np.abs(log_ratio - median))) > tc.merge_max_scale_spread:
            return None
        return float(np.exp(median))


def _distances(T_cw: np.ndarray, X: np.ndarray) -> np.ndarray:
    return np.linalg.norm(X @ T_cw[:3, :3].T + T_cw[:3, 3], axis=1)
