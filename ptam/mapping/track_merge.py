"""Merging another track's map into the mapper's (Gauglitz et al. TVCG 2013 §5.3).

Two tracks that saw the same part of the scene are related by a similarity: X_this = s·R·X_other + t (each
track has its own frame and scale, §4.4). The other track's keyframes, points, measurements and edgelets are
appended to this map, moved by it; the features that linked the two tracks become measurements, and each map's
points are queued for re-finding in the other's keyframes (PTAM code ``ReFindNewlyMade``), so that bundle
adjustment ties the two parts together instead of adjusting two unconnected maps.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..geometry.sim3 import Similarity
from ..map.map import SRC_REFIND, Map
from ..map.snapshot import MapSnapshot
from .edgelet_measurements import rebuild_visibility_tables

if TYPE_CHECKING:
    from .map_maker import MapMaker


@dataclass(frozen=True)
class Link:
    """Features connecting the two tracks: the other track's points ``point_ids`` found in this map's keyframe
    ``keyframe`` at level-0 pixels ``xy`` on pyramid levels ``level`` (the verifying tracking step)."""

    keyframe: int
    point_ids: np.ndarray
    xy: np.ndarray
    level: np.ndarray


def append_map(m: Map, other: MapSnapshot, sim: Similarity) -> tuple[int, int]:
    """Append ``other``'s content to ``m``, moved by ``sim``; returns (first new keyframe, first new point)."""
    k0, p0 = m.n_keyframes, m.n_points_total
    poses = sim.poses_cw(other.kf_T_cw)
    part = 1 + max(kf.part for kf in m.keyframes)  # the other map's own keyframes, and the parts it had merged
    for kf, T in zip(other.keyframes, poses):  # once per keyframe of a merge
        m.add_keyframe(dataclasses.replace(kf, id=m.next_keyframe_id, part=part + kf.part), T)
    normal = other.normal @ sim.R.T
    m.add_points(sim.points(other.X), normal, other.source_kf + k0, other.source_level, other.source_xy, other.ray)
    if other.bad.any():
        m.mark_bad(np.flatnonzero(other.bad) + p0)
    m.add_measurements(other.meas_kf + k0, other.meas_pt + p0, other.meas_xy, other.meas_level, other.meas_source)
    if len(other.edgelet_centre):
        e0 = m.edgelets.n_total
        m.add_edgelets(
            sim.points(other.edgelet_centre), other.edgelet_direction @ sim.R.T, other.edgelet_normal @ sim.R.T,
            other.edgelet_source_kf + k0,
        )  # fmt: skip
        if other.edgelet_bad.any():
            m.mark_edgelets_bad(np.flatnonzero(other.edgelet_bad) + e0)
        if len(other.edgelet_meas_kf):
            m.add_edgelet_measurements(
                other.edgelet_meas_kf + k0, other.edgelet_meas_edgelet + e0, other.edgelet_meas_a, other.edgelet_meas_b
            )
    return k0, p0


def absorb(mapper: MapMaker, other: MapSnapshot, sim: Similarity, link: Link) -> None:
    """Merge ``other`` into ``mapper``'s map (in the mapper's thread: only it mutates the map), link the two
    parts, and leave a global bundle adjustment to do (PTAM §6.3)."""
    m = mapper.map
    n_before, e_before = m.n_points_total, m.edgelets.n_total
    k0, p0 = append_map(m, other, sim)
    ids = link.point_ids + p0
    ok = ~m.bad[ids]
    m.add_measurements(link.keyframe, ids[ok], link.xy[ok], link.level[ok], SRC_REFIND)
    if mapper.cfg.edgelets.enabled:
        rebuild_visibility_tables(m, mapper.cfg, first_kf=k0)
    mapper.queue_refind(np.arange(p0, m.n_points_total), 0)  # the other's points in this track's keyframes
    mapper.queue_refind(np.arange(n_before), k0)  # this track's points in the other's keyframes
    if mapper.cfg.edgelets.enabled:  # and so the edgelets (Agility §4.4)
        mapper.edgelets.queue(np.arange(e_before, m.edgelets.n_total), 0)
        mapper.edgelets.queue(np.arange(e_before), k0)
    mapper.full_converged = False
    mapper.publish()
