"""Whether a frame shows motion blur, from its corners (Agility §1): ``ptam.tracking.blur_evidence``."""

from types import SimpleNamespace

import cv2
import numpy as np

from ptam.config import load_config
from ptam.image.pyramid import Pyramid
from ptam.synthetic.texture import check_texture, make_texture
from ptam.tracking.blur_evidence import shows_blur

FOCAL_PX = 384.0  # two_wall's camera


def _texture() -> np.ndarray:
    """640x480 of two_wall's dead leaves with the renderer's one-pixel optics blur."""
    spec = {"type": "dead_leaves", "seed": 1, "texel": 0.005, "sizes": [0.04, 1.2], "exponent": 2.5, "coverage": 3}
    tex, _ = make_texture(check_texture(spec, "test"), 3.2, 2.4, "test")
    return cv2.GaussianBlur(tex[:480, :640].astype(np.float32), (0, 0), 1.0).round().astype(np.uint8)


def _smeared(img: np.ndarray, length_px: float) -> Pyramid:
    k = np.full((1, round(length_px)), 1.0 / round(length_px))
    return Pyramid.build(cv2.filter2D(img, -1, k, borderType=cv2.BORDER_REFLECT), load_config().image)


def test_a_frame_shows_blur_when_it_lost_half_the_keyframes_corners():
    """two_wall's texture and focal length. A frame turning at the rapid threshold (3 degrees a frame) and exposed
    for half of it is smeared 10 px: as blurred as a slow frame may be, it keeps 80 % of its corners. A pan at
    three times that keeps 8 %; a rapid frame with a short exposure (sharp, moved 30 px) keeps them all."""
    cfg = load_config()
    tex = _texture()
    keyframe = Pyramid.build(tex, cfg.image)
    at_threshold = np.radians(cfg.reloc.rapid_rotation_deg) * FOCAL_PX * cfg.tracker.exposure_fraction
    frames = {
        "sharp": Pyramid.build(np.roll(tex, 30, axis=1), cfg.image),
        "smeared at the threshold": _smeared(tex, at_threshold),
        "smeared by a fast pan": _smeared(tex, 3 * at_threshold),
    }
    n = len(keyframe.corners[0])
    kept = {name: len(p.corners[0]) / n for name, p in frames.items()}
    assert kept["sharp"] > 0.95 and kept["smeared at the threshold"] > 0.7 and kept["smeared by a fast pan"] < 0.2, kept
    snapshot = SimpleNamespace(n_keyframes=1, keyframes=[SimpleNamespace(pyramid=keyframe)])
    snapshot.nearest_keyframe = lambda T: (0, 0.0)
    fraction = cfg.tracker.blur_corner_fraction
    blurred = {name: shows_blur(p, snapshot, np.eye(4), fraction) for name, p in frames.items()}
    assert blurred == {"sharp": False, "smeared at the threshold": False, "smeared by a fast pan": True}
    assert shows_blur(frames["sharp"], snapshot, np.eye(4), np.inf)  # .inf: blur always assumed (Agility)
    assert shows_blur(frames["sharp"], None, np.eye(4), fraction)  # no keyframe: the assumed exposure stands
