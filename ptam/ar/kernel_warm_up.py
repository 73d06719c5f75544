"""Loading the overlay's kernels before the first frame, as ``ptam.system.warm_up`` does for the tracker's.

The rasteriser's numba kernels (``raster_kernels``) are compiled on the first run after an install and loaded
from the cache in every later process, both holding the GIL. Loaded lazily they were loaded on the AR worker's
first frame: the frame that completes stereo initialisation, when the tracker has its youngest map and the mapper
its first bundle adjustments. So :class:`~ptam.ar.layer.ArLayer` draws every scene once, off screen, before it
takes frames (once per process): from a camera above the plane's origin, where the eyes, the game's targets and
the grid are in view, over a grey frame and a colour one.
"""

from __future__ import annotations

import threading

import numpy as np

from ..geometry import se3
from ..vocabulary import ArScene
from .augmenter import Augmenter
from .scenes import SCENES

_HEIGHT_M = 0.5  # the camera above the plane's origin, looking down at it ...
_TILT_DEG = 20.0  # ... turned about its x axis, so spheres, their shadows and the grid all show
_FRAMES = 2  # the game rolls its targets in from its second frame on

_lock = threading.Lock()
_done = False


def _looking_down() -> np.ndarray:
    """T_cw of a camera ``_HEIGHT_M`` above the world (= initial plane) frame's origin, +z of the plane towards it,
    looking at the origin."""
    a = np.radians(_TILT_DEG)
    R_wc = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])  # camera axes in the world: down
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])
    R_wc = R_wc @ tilt
    centre = -_HEIGHT_M * R_wc[:, 2]  # the optical axis through the origin
    return se3.inv(se3.from_Rt(R_wc, centre))


def warm_overlay_kernels(camera, cfg) -> None:
    """Draw every AR scene over a blank grey and a blank colour frame of ``camera``'s size (once per process)."""
    global _done
    with _lock:
        if _done:
            return
        T_cw = _looking_down()
        W, H = camera.size
        grey = np.full((H, W), 128, np.uint8)
        colour = np.full((H, W, 3), 128, np.uint8)
        aug = Augmenter(camera, cfg, ArScene.OFF)  # one renderer (its ray table) for every scene
        for name in SCENES:
            if name == ArScene.OFF:
                continue
            aug.set_scene(name)
            for i in range(_FRAMES):
                aug.augment(grey, T_cw, i / cfg.capture.default_fps, grey_ok=True)
                aug.augment(colour, T_cw, (i + 0.5) / cfg.capture.default_fps)
        _done = True
