"""The mapper's edgelet work (Agility §4.3-§4.4): one job per new keyframe, and the new edgelets' measurements in
the old keyframes, which wait, as PTAM's new points wait for ``ReFindNewlyMade``, until the mapper is idle."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from .edgelet_images import EdgeImages
from .edgelet_mapping import integrate_keyframe
from .edgelet_measurements import measure_newly_made

if TYPE_CHECKING:
    from collections.abc import Callable

    from ..camera.model import CameraModel
    from ..config import Config
    from ..map.map import Map


class EdgeletWork:
    def __init__(self, camera: CameraModel, cfg: Config) -> None:
        self.camera = camera
        self.cfg = cfg
        self.images = EdgeImages(cfg.edgelets)  # kept between jobs (Agility §4.3)
        self._new: list[tuple[np.ndarray, int]] = []  # (edgelet ids, next keyframe to measure them in)

    @property
    def pending(self) -> bool:
        return bool(self._new)

    def integrate(self, m: Map, k: int, stats: dict) -> None:
        """The edgelet job for new keyframe k, its target the nearest keyframe (``edgelet_mapping``); its new
        edgelets wait to be measured in the old keyframes."""
        first = m.edgelets.n_total
        job = integrate_keyframe(m, self.camera, self.cfg, k, m.nearest_with_baseline(k), self.images)
        stats.setdefault("edgelet_jobs", []).append(job)
        if m.edgelets.n_total > first:  # the job appends its new edgelets
            self.queue(np.arange(first, m.edgelets.n_total), 0)

    def queue(self, ids: np.ndarray, first_kf: int) -> None:
        """Measure edgelets ``ids`` in keyframes ``first_kf`` on that do not measure them, when idle."""
        self._new.append((np.asarray(ids, np.int64), first_kf))

    def measure_pending(self, m: Map, abort: Callable[[], bool], stats: dict) -> None:
        """The oldest queued edgelets measured in their keyframes; a queued keyframe (``abort``) interrupts it."""
        ids, start = self._new.pop(0)
        c = time.perf_counter()
        resume = measure_newly_made(m, self.camera, self.cfg, ids, start, abort)
        stats.setdefault("edgelet_old_keyframes_ms", []).append(1e3 * (time.perf_counter() - c))
        if resume >= 0:
            self._new.insert(0, (ids, resume))
