"""A scene whose only intensity edges are known 3-D lines: three plain cards at different depths and slants over
a plain background, rendered into keyframes at known poses (the edgelet map and tracking tests)."""

from __future__ import annotations

import functools

import cv2
import numpy as np

from ptam.geometry import se3
from ptam.image.pyramid import Pyramid
from ptam.map.keyframe import KeyFrame
from ptam.map.map import Map
from ptam.synthetic.rectangle import Rectangle
from ptam.synthetic.render import Renderer

BACKGROUND = 40.0
LOOK_AT = np.array([0.0, 0.0, 1.1])
DEPTH_MEAN, DEPTH_SIGMA = 1.1, 0.25
# (centre, in-plane turn deg, tilt axis, tilt deg, size, grey)
_CARDS = (
    ((0.02, -0.01, 1.1), 15.0, (0, 1, 0), 25.0, (0.4, 0.3), 200.0),
    ((0.36, 0.2, 1.25), -12.0, (1, 0, 0), -20.0, (0.2, 0.22), 130.0),
    ((-0.33, -0.22, 0.98), 35.0, (1, 1, 0), 15.0, (0.18, 0.14), 165.0),
)


def _rot(axis, deg):
    axis = np.asarray(axis, float)
    return cv2.Rodrigues(axis / np.linalg.norm(axis) * np.deg2rad(deg))[0]


def cards() -> list[Rectangle]:
    out = []
    for i, (centre, turn, axis, tilt, size, grey) in enumerate(_CARDS):
        R = _rot(axis, tilt) @ _rot([0, 0, 1], turn)
        a, b = R[:, 0], R[:, 1]
        corner0 = np.asarray(centre) - a * size[0] / 2 - b * size[1] / 2
        out.append(Rectangle(f"card{i}", corner0, a, b, size, {"type": "constant", "value": grey}))
    return out


def true_edges() -> tuple[np.ndarray, np.ndarray]:
    """Every card side as a segment: start points (S, 3) and ends (S, 3)."""
    q = np.array([c.corners() for c in cards()])
    return q.reshape(-1, 3), np.roll(q, -1, axis=1).reshape(-1, 3)


def edge_errors(centre: np.ndarray, direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (m) of each edgelet centre from the nearest card side, and the angle (deg) between the
    edgelet's direction and that side."""
    P, Q = true_edges()
    U = (Q - P) / np.linalg.norm(Q - P, axis=1, keepdims=True)
    lam = np.clip(np.einsum("nsk,sk->ns", centre[:, None] - P[None], U), 0.0, np.linalg.norm(Q - P, axis=1))
    dist = np.linalg.norm(centre[:, None] - (P[None] + lam[..., None] * U[None]), axis=2)
    j = dist.argmin(axis=1)
    cos = np.abs(np.sum(direction * U[j], axis=1))
    return dist[np.arange(len(centre)), j], np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))


def look_at(pos, target=LOOK_AT) -> np.ndarray:
    """T_cw of a camera at ``pos`` looking at ``target`` (y down)."""
    pos = np.asarray(pos, float)
    z = (target - pos) / np.linalg.norm(target - pos)
    x = np.cross([0.0, -1.0, 0.0], z)
    x /= np.linalg.norm(x)
    return se3.inv(se3.from_Rt(np.stack([x, np.cross(z, x), z], axis=1), pos))


@functools.lru_cache(maxsize=2)
def _renderer(camera, samples: int) -> Renderer:
    """The cards' renderer for a camera (by identity): its rays take seconds to build at 6×6 samples a pixel, and
    the tests render many keyframes through the same two cameras."""
    return Renderer(camera, cards(), samples, BACKGROUND)


def render(camera, T_cw: np.ndarray, seed: int, samples: int = 6) -> np.ndarray:
    """The cards seen from the poses T_cw (P, 4, 4), averaged (P > 1: motion blur), with a 0.7 px lens blur and
    one grey level of noise."""
    img = _renderer(camera, samples).render(se3.inv(np.asarray(T_cw).reshape(-1, 4, 4)))
    img = cv2.GaussianBlur(img, (0, 0), 0.7) + np.random.default_rng(seed).normal(0, 1.0, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def keyframe_map(camera, image_cfg, positions) -> Map:
    """A map of keyframes at ``positions`` (K, 3) looking at the cards, with the scene's depth prior."""
    m = Map()
    for i, p in enumerate(positions):
        T = look_at(p)
        pyramid = Pyramid.build(render(camera, T, seed=i), image_cfg)
        m.add_keyframe(KeyFrame(i, pyramid, DEPTH_MEAN, DEPTH_SIGMA), T)
    return m
