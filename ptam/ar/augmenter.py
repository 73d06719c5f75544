"""One augmented frame from a frame and its pose: the dominant plane, a scene and the renderer together."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import se3
from .ar_plane import ArPlane
from .drawlist import DrawList
from .overlay import OverlayRenderer
from .scenes import make_scene


@dataclass(frozen=True)
class ArStep:
    """A scene's frame, ready to draw: the plane→camera pose and what the scene draws."""

    T_cp: np.ndarray
    drawlist: DrawList


class Augmenter:
    """``T_pw``: the plane frame (world→plane) to start from; by default the world frame, whose z = 0 is the
    dominant plane after stereo initialisation (PTAM §6.1)."""

    def __init__(self, camera, cfg, scene: str | None = None, T_pw: np.ndarray | None = None):
        self.plane = ArPlane(cfg.init, cfg.ar.plane_refresh_growth, T_pw)
        self.ar_cfg = cfg.ar
        self.scene = make_scene(scene or cfg.ar.scene, cfg.ar)
        self.renderer = OverlayRenderer(camera, cfg.ar)
        self._last_timestamp: float | None = None

    def set_scene(self, name: str) -> None:
        """Switch to a new scene ``name`` (started afresh: the eyes' grid fades again, the game's score restarts)."""
        self.scene = make_scene(name, self.ar_cfg)

    def advance(self, T_cw: np.ndarray, timestamp: float, snapshot=None) -> ArStep:
        """The scene's next frame for world→camera pose ``T_cw``; ``snapshot`` (the map) lets the plane refresh
        as the map grows. Every tracked frame advances the scene, drawn or not: its state counts frames (the
        eyes turn so far per frame, the grid fades and a target is hit after so many frames)."""
        self.plane.maybe_refresh(snapshot)
        T_cp = np.asarray(T_cw, np.float64) @ se3.inv(self.plane.T_pw)
        dt = 0.0 if self._last_timestamp is None else float(timestamp) - self._last_timestamp
        self._last_timestamp = float(timestamp)
        return ArStep(T_cp, self.scene.update(se3.inv(T_cp), dt))

    def draw(self, image: np.ndarray, step: ArStep, grey_ok: bool = False) -> np.ndarray:
        """BGR uint8 frame: ``image`` with ``step`` drawn over it; ``grey_ok``: grey (H, W) when the frame and the
        overlay are both grey (``OverlayRenderer.render``)."""
        return self.renderer.render(image, step.T_cp, step.drawlist, grey_ok)

    def augment(
        self, image: np.ndarray, T_cw: np.ndarray, timestamp: float, snapshot=None, grey_ok: bool = False
    ) -> np.ndarray:
        """BGR uint8 frame with the scene's next frame drawn for world→camera pose ``T_cw`` (``grey_ok``: as
        :meth:`draw`)."""
        return self.draw(image, self.advance(T_cw, timestamp, snapshot), grey_ok)
