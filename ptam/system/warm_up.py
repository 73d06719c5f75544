"""Loading every kernel before the first frame arrives: a short synthetic rehearsal.

numba's ``cache=True`` kernels are compiled on the first run after an install (about 35 s for all of them on two
cores) and loaded from the cache on their first call in every later process (milliseconds each). Both hold the
GIL. Done lazily, the tracker's first frames paid for the per-frame kernels, and the mapper's first keyframes
for the mapper's: bundle adjustment, the edgelets (Agility §4), the epipolar searches. On a live camera that
drops frames just when the map is young; after an install it held the tracker for seconds while the first map
was being refined (two_wall in ``realtime`` mode from empty caches: 14 % of the frames correct, 11 wrong poses
reported as tracked, against 100 % and none once compiled).

So before the source starts delivering, ``System.start`` runs a ``sync`` System over ``rehearsal_frames``: the
user's camera sliding sideways past a slanted dead-leaves plane. Its ``system.warm_up_frames`` frames take the
whole pipeline through stereo initialisation, tracking with points and edgelets, four keyframes, new points
and edgelets, and local and global bundle adjustment. The plane is slanted so that the keyframes see a spread
of depths (the mapper's epipolar searches span the scene's depth range, which a fronto-parallel plane has not).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Iterator

import cv2
import numpy as np

from ..camera.model import CameraModel
from ..capture.frame import Frame
from ..synthetic.texture import make_texture

_DEPTH_M = 1.0  # the plane's distance along the first frame's optical axis
_SLANT_DEG = 30.0  # the plane turned about the image's vertical axis, for a spread of depths
_STEP_M = 0.01  # sideways per frame: PTAM's stereo baseline (10 % of the depth) after ten frames
_FPS = 30.0
_TEXTURE = {
    "type": "dead_leaves",
    "seed": 0,
    "texel": 0.002,
    "sizes": [0.04, 0.4],
    "exponent": 2.5,
    "coverage": 1.0,
    "grey": [20, 235],
}
_MARGIN_M = 1.0  # texture beyond what the first and last frames see of the plane's centre line
_HEIGHT_M = 2.0  # the texture's extent up and down; rays beyond it see the texture reflected
_BLUR_PX = 0.7  # a lens's blur: the dead leaves' edges are one texel sharp
_NOTICE_AFTER_S = 3.0  # a rehearsal with the kernels cached takes 0.6-1.3 s on two cores; compiling them 35 s


@contextlib.contextmanager
def rehearsal_log(log: logging.Logger) -> Iterator[None]:
    """The rehearsal's own log lines (map initialised, ...) are held back: they are not the user's map. If it takes
    longer than ``_NOTICE_AFTER_S`` (the kernels are being compiled, or the camera's images are large), one line
    says why the start waits, and one how long it took; a quick one prints nothing."""
    level, t0 = log.level, time.perf_counter()
    noticed = threading.Event()

    def notice() -> None:
        noticed.set()
        log.warning("loading the kernels on a short rehearsal (the first run after an install compiles them: ~30 s)")

    timer = threading.Timer(_NOTICE_AFTER_S, notice)
    timer.daemon = True
    log.setLevel(logging.WARNING)
    timer.start()
    try:
        yield
    finally:
        timer.cancel()
        log.setLevel(level)
    if noticed.is_set():
        log.info("kernels ready after %.0f s", time.perf_counter() - t0)


def rehearsal_frames(camera: CameraModel, n: int) -> Iterator[Frame]:
    """``n`` frames of the camera translating along its x axis by ``_STEP_M`` a frame in front of a plane that
    crosses the optical axis at ``_DEPTH_M``, turned by ``_SLANT_DEG`` about the y axis; rendered through the
    camera's own lens model (``unproject`` of every pixel, then ``cv2.remap`` of the texture)."""
    a = np.deg2rad(_SLANT_DEG)
    normal = np.array([-np.sin(a), 0.0, np.cos(a)])  # towards the camera
    across = np.array([np.cos(a), 0.0, np.sin(a)])  # the plane's in-plane axis that the camera slides along
    width_m = n * _STEP_M / np.cos(a) + 2 * _MARGIN_M
    texture, texel = make_texture(_TEXTURE, width_m, _HEIGHT_M, "warm-up texture")
    u, v = np.meshgrid(np.arange(camera.width, dtype=np.float64), np.arange(camera.height, dtype=np.float64))
    xy = camera.unproject(np.stack([u.ravel(), v.ravel()], axis=-1))
    rays = np.concatenate([xy, np.ones((len(xy), 1))], axis=1)
    r_normal = rays @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_r_normal = np.where(r_normal > 0, 1.0 / r_normal, np.nan)  # rays that never meet the plane: NaN
    r_across, r_up = rays @ across, rays[:, 1]
    d0 = _DEPTH_M * normal[2]  # the plane n.X = d0 passes through (0, 0, _DEPTH_M)
    origin = _MARGIN_M - _DEPTH_M * across[2]  # the texture starts _MARGIN_M before the plane point (0, 0, _DEPTH_M)
    shape = (camera.height, camera.width)
    for i in range(n):
        x = i * _STEP_M  # the camera centre (x, 0, 0)
        s = (d0 - x * normal[0]) * inv_r_normal  # distance along each ray to the plane
        map_x = np.nan_to_num((x * across[0] + s * r_across + origin) / texel, nan=-1.0).reshape(shape)
        map_y = np.nan_to_num((s * r_up + 0.5 * _HEIGHT_M) / texel, nan=-1.0).reshape(shape)
        img = cv2.remap(
            texture, map_x.astype(np.float32), map_y.astype(np.float32), cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT
        )
        img = cv2.GaussianBlur(img, (0, 0), _BLUR_PX)
        yield Frame(i, i / _FPS, np.clip(img, 0, 255).astype(np.uint8))
