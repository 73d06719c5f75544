"""Keyframe images as the edgelet job's epipolar search reads them (Agility §4.3).

The search smooths a target keyframe's image (Canny's input and the polarity gradient's) and matches epipolar
curves against its maximal edgels. A keyframe is the target of the next keyframe's job, when its smoothed image
was already made for its own candidates, and the aperture retry's second target is often one keyframe for several
jobs (desk_bricks: 7 of 13). ``EdgeImages`` keeps both images of the ``edgelets.image_cache_keyframes`` keyframes
used last, each entry holding the keyframe image it was made from, so a map that replaced its keyframes (a reset,
a file loaded) is never served another map's images.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import cv2
import numpy as np

from ..config import EdgeletConfig
from ..edgelet import maximal_edgels, smoothed
from ..map.map import Map


@dataclass
class _Entry:
    source: np.ndarray  # the keyframe's full-size image
    smoothed: np.ndarray
    maximal: np.ndarray | None = None  # dilated by ``epipolar_dilate_px``


class EdgeImages:
    """Smoothed and maximal-edgel images of the keyframes used last (one job reads at most three keyframes)."""

    def __init__(self, cfg: EdgeletConfig) -> None:
        self.cfg = cfg
        self._entries: OrderedDict[int, _Entry] = OrderedDict()

    def _entry(self, m: Map, k: int) -> _Entry:
        image = m.keyframes[k].pyramid.levels[0]
        entry = self._entries.get(k)
        if entry is None or entry.source is not image:
            entry = _Entry(image, smoothed(image, self.cfg))
            self._entries[k] = entry
        self._entries.move_to_end(k)
        while len(self._entries) > self.cfg.image_cache_keyframes:
            self._entries.popitem(last=False)
        return entry

    def smoothed(self, m: Map, k: int) -> np.ndarray:
        return self._entry(m, k).smoothed

    def maximal(self, m: Map, k: int) -> np.ndarray:
        """Keyframe k's maximal edgels (``maximal_edgels``), grown by ``epipolar_dilate_px``."""
        entry = self._entry(m, k)
        if entry.maximal is None:
            edgels = maximal_edgels(entry.smoothed, self.cfg)
            d = self.cfg.epipolar_dilate_px
            entry.maximal = cv2.dilate(edgels, np.ones((2 * d + 1,) * 2, np.uint8)) if d else edgels
        return entry.maximal
