"""Keyframe groups (Gauglitz et al. TVCG 2013 §3.2, §4.3): the sub-maps a keyframe graph is made of.

An SfM group holds keyframes linked by 3-D pose information: the keyframes PTAM's mapper triangulates between
(one group per map; ptam keeps a single track). A panorama group holds keyframes related by rotations about one
centre: consecutive keyframes taken under rotation-only motion, together with the SfM keyframe whose centre they
turn about (§4.3: "a new keyframe group consisting of k_new and the previous keyframe k_prev"), which is also
the group's link to the SfM group. Groups are derived from the keyframes' kinds and poses, so a map file needs
no extra record of them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..vocabulary import GroupKind
from .keyframe import KeyFrame
from .snapshot import MapSnapshot


@dataclass(frozen=True)
class KeyframeGroup:
    kind: GroupKind
    keyframes: tuple[int, ...]  # keyframe indices; a panorama group's first one is its SfM parent (or -1: none)


def keyframe_groups(snapshot: MapSnapshot) -> list[KeyframeGroup]:
    """The SfM group, then one panorama group per SfM keyframe that panorama keyframes turn about (the SfM
    keyframe nearest to their centres)."""
    pano = KeyFrame.panorama_flags(snapshot.keyframes)
    sfm = np.flatnonzero(~pano)
    groups = [KeyframeGroup(GroupKind.SFM, tuple(sfm.tolist()))] if len(sfm) else []
    if not pano.any():
        return groups
    centres = snapshot.camera_centres
    ids = np.flatnonzero(pano)
    if len(sfm):
        parent = sfm[np.linalg.norm(centres[ids][:, None] - centres[sfm][None], axis=2).argmin(axis=1)]
    else:
        parent = np.full(len(ids), -1)
    for p in np.unique(parent):
        groups.append(KeyframeGroup(GroupKind.PANORAMA, (int(p), *ids[parent == p].tolist())))
    return groups
