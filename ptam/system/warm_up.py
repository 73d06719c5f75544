"""Loading the per-frame kernels before the first frame arrives.

numba's ``cache=True`` kernels are compiled once per machine but still loaded on their first call; the tracker's
first frames each touch a few more of them (~0.2 s at frame 0, ~50 ms at the first tracked frame), which at
30 Hz drops frames just when initialisation and the first pose matter most. ``warm_up`` runs one frame of every
per-frame path — pyramid, trails, rotation estimate, point tracking against a one-keyframe map, and before the
map the panorama's first keyframe and the model-free check — on a synthetic image, before the source starts
delivering.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..camera.model import CameraModel
from ..config import Config
from ..image.pyramid import Pyramid
from ..map.keyframe import KeyFrame
from ..map.map import SRC_ROOT, Map
from ..tracking.tracker import Tracker
from ..tracking.trails import TrailTracker
from .rotation_start import RotationStart

_TEXTURE_BLUR_PX = 1.5  # corners need some smoothness; any texture that FAST fires on serves
_DEPTH = 1.0  # the synthetic points sit on a fronto-parallel plane this far away (map units)


def warm_up(camera: CameraModel, cfg: Config) -> None:
    rng = np.random.default_rng(0)
    noise = cv2.GaussianBlur(rng.random((camera.height, camera.width)), (0, 0), _TEXTURE_BLUR_PX)
    image = (255 * (noise - noise.min()) / np.ptp(noise)).astype(np.uint8)
    pyramid = Pyramid.build(image, cfg.image)
    trails = TrailTracker(cfg.init, cfg.image)
    if trails.start(pyramid) == 0:
        return
    trails.advance(pyramid)
    m = Map()
    m.add_keyframe(KeyFrame(0, pyramid, _DEPTH, 0.0, 0.0), np.eye(4))
    xy = trails.start_xy.astype(np.float64)
    rays = camera.unproject(xy)
    X = np.concatenate([rays * _DEPTH, np.full((len(xy), 1), _DEPTH)], axis=1)
    ids = m.add_points(X, np.broadcast_to([0.0, 0.0, -1.0], X.shape), 0, 0, xy)
    m.add_measurements(0, ids, xy, 0, SRC_ROOT)
    tracker = Tracker(camera, cfg)
    snapshot = m.snapshot()
    tracker.track(image, snapshot)
    tracker.set_pose(np.eye(4), recovered=True)  # the enlarged coarse stage of a recovered pose
    tracker.track(image, snapshot)
    ms = cfg.model_selection
    if ms.enabled and ms.initialisation_free:  # the panorama before the map: rays, and the model-free check
        start = RotationStart(camera, cfg, background=False)
        if start.begin(pyramid, 0, 0.0) is not None:
            start.follow(image, pyramid)
