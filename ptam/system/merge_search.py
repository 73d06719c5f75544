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
from ..geometry import se3
from ..geometry.sim3 import Similarity
from ..map.snapshot import MapSnapshot
from ..mapping.track_merge import Link
from ..tracking.relocaliser import Relocaliser, confirms
from ..tracking.tracker import Tracker


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
        kf = snap.keyframes[k1]
        reloc = self._relocalisers.setdefault(other, Relocaliser(self.camera, self.cfg)).attempt(kf.pyramid, osnap)
        if reloc is None or not reloc.accepted:
            return None
        res = self._tracked(kf, osnap, reloc.T_cw, self.cfg.reloc.confirm_frames)
        if res is None:
            return None
        m = res.measurements
        sel = m.found & m.inlier
        link = Link(k1, m.point_ids[sel], m.xy[sel], m.level[sel])
        s = self._scale(snap, k1, osnap, res.T_cw, link)
        if s is None:
            return None
        T_b, T_a = snap.kf_T_cw[k1], res.T_cw
        R = T_b[:3, :3].T @ T_a[:3, :3]
        t = T_b[:3, :3].T @ (s * T_a[:3, 3] - T_b[:3, 3])
        sim = Similarity(R, t, s)
        return Overlap(other, sim, link) if self._consistent(snap, k1, osnap, sim) else None

    def _tracked(self, kf, osnap: MapSnapshot, T_cw: np.ndarray, passes: int, recovered: bool = True):
        """``passes`` tracking steps of keyframe ``kf``'s image against ``osnap`` from ``T_cw``: the last result,
        or None unless every pass is good with most patches Tukey inliers (the relocaliser's confirmation)."""
        tracker = self.tracker
        tracker.reset()
        tracker.set_pose(T_cw, recovered=recovered)
        res = None
        for _ in range(passes):
            res = tracker.track(kf.pyramid.levels[0], osnap, kf.pyramid)
            if not confirms(res, self.cfg.reloc):
                return None
            tracker.set_pose(res.T_cw)
        return res

    def _consistent(self, snap: MapSnapshot, k1: int, osnap: MapSnapshot, sim: Similarity) -> bool:
        """The whole current track agrees with the merge: every other keyframe of it from which the other map's
        points would be in view (``tracks.merge_min_common`` or more, placed by ``sim``) tracks against that map
        from its predicted pose, and the other map explains the keyframe's image as well as its own map does:
        the inlier fractions differ by no more than ``tracks.merge_agreement_sigmas`` binomial standard
        deviations. Two look-alike places (twin posters) agree where they look alike, not in their surroundings,
        where the other map has something else (desk_twins: 0.54-0.60 of the patches against about 0.9)."""
        predicted = sim.inverse().poses_cw(snap.kf_T_cw)
        z = self.cfg.tracks.merge_agreement_sigmas
        for k in range(snap.n_keyframes):  # once per keyframe of a candidate merge
            if k == k1 or _in_view(self.camera, predicted[k], osnap) < self.cfg.tracks.merge_min_common:
                continue
            kf = snap.keyframes[k]
            other = self._tracked(kf, osnap, predicted[k], 1, recovered=False)
            if other is None:
                return False
            own = self._tracked(kf, snap, snap.kf_T_cw[k], 1, recovered=False)
            if own is None:  # its own map does not explain it either: no evidence either way
                continue
            f = own.inlier_fraction
            if other.inlier_fraction < f - z * np.sqrt(f * (1.0 - f) / max(other.n_attempted, 1)):
                return False
        return True

    def _scale(self, snap: MapSnapshot, k1: int, osnap: MapSnapshot, T_a: np.ndarray, link: Link) -> float | None:
        """Gauglitz §4.3: the median ratio of the common features' distances to k1 in the two frames (this track's
        over the other's); None when too few features are common or their ratios disagree."""
        tc = self.cfg.tracks
        a = ~osnap.ray[link.point_ids]
        xy_a, d_a = link.xy[a], _distances(T_a, osnap.X[link.point_ids[a]])
        in_k1 = snap.meas_kf == k1
        mine = snap.meas_pt[in_k1]
        b = ~snap.ray[mine] & ~snap.bad[mine]
        xy_b, d_b = snap.meas_xy[in_k1][b], _distances(snap.kf_T_cw[k1], snap.X[mine[b]])
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


def _in_view(camera: CameraModel, T_cw: np.ndarray, snap: MapSnapshot) -> int:
    """How many of ``snap``'s good points (not rays) project into the image in front of a camera at ``T_cw``."""
    ids = snap.good_point_indices[~snap.ray[snap.good_point_indices]]
    Xc = se3.transform(T_cw, snap.X[ids])
    Xc = Xc[camera.valid(Xc)]
    return int(np.count_nonzero(camera.in_image(camera.project(Xc)))) if len(Xc) else 0


def _distances(T_cw: np.ndarray, X: np.ndarray) -> np.ndarray:
    return np.linalg.norm(se3.transform(T_cw, X), axis=1)
