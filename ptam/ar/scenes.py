"""The AR scenes picked by ``ptam run --ar``: each turns the camera pose into a ``DrawList`` every frame.

- ``grid``: the dominant plane's grid (PTAM Fig. 1).
- ``eyes``: PTAM code's EyeGame: the eyeballs following the camera, over a grid that fades out between
  ``ar.grid_fade_frames`` (PTAM code ``DrawFadingGrid``).
- ``game``: §7.5-style shooting: targets roll in on the eyes over a faint grid; the optical axis meets the
  plane as the cross-hair, with a dwell gauge and the score.
- ``off``: nothing (the video then holds the plain frames).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from ..vocabulary import ArScene
from .drawlist import DrawList
from .eyes import Eyes
from .game import TargetGame

SCENES = tuple(ArScene)


class Scene:
    name = ArScene.OFF

    def __init__(self, ar_cfg):
        self.cfg = ar_cfg
        self.frames = 0

    def update(self, T_pc: np.ndarray, dt: float) -> DrawList:
        """The next frame's drawing for camera→plane pose ``T_pc``, ``dt`` seconds after the previous one."""
        self.frames += 1
        return self._update(T_pc, dt)

    def _update(self, T_pc, dt) -> DrawList:
        return DrawList()

    def fire(self) -> None:
        """A key press; only the game uses it."""


class GridScene(Scene):
    name = ArScene.GRID

    def _update(self, T_pc, dt):
        return DrawList(grid_alpha=1.0)


class EyesScene(Scene):
    name = ArScene.EYES

    def __init__(self, ar_cfg):
        super().__init__(ar_cfg)
        self.eyes = Eyes(ar_cfg)

    def _update(self, T_pc, dt):
        self.eyes.look_at(T_pc[:3, 3])
        a, b = self.cfg.grid_fade_frames
        fade = 1.0 if self.frames < a else max(0.0, (b - self.frames) / max(b - a, 1))
        return DrawList(self.eyes.spheres(), self.eyes.shadows(), grid_alpha=fade)


class GameScene(Scene):
    name = ArScene.GAME

    def __init__(self, ar_cfg):
        super().__init__(ar_cfg)
        self.eyes = Eyes(ar_cfg)
        # The four eyes fit in a disc of (1 + sqrt 2) radii around the plane origin.
        self.game = TargetGame(ar_cfg, (1.0 + math.sqrt(2.0)) * ar_cfg.eye_radius)

    def fire(self) -> None:
        self.game.fire()

    def _update(self, T_pc, dt):
        self.eyes.look_at(T_pc[:3, 3])
        self.game.step(T_pc, dt)
        g = self.game
        spheres = np.concatenate([self.eyes.spheres(), g.spheres()])
        decals = np.concatenate([self.eyes.shadows(), g.decals()])
        return DrawList(
            spheres,
            decals,
            grid_alpha=self.cfg.game_grid_alpha,
            crosshair=True,
            crosshair_locked=g.aimed >= 0,
            dwell=g.dwell_fraction,
            text=[f"hits {g.hits}   bites {g.bites}"],
        )


_SCENES = {ArScene.EYES: EyesScene, ArScene.GAME: GameScene, ArScene.GRID: GridScene, ArScene.OFF: Scene}


def make_scene(name: str, ar_cfg) -> Scene:
    if name not in _SCENES:
        raise InputError(f"unknown AR scene '{name}' (choose from {', '.join(SCENES)})")
    return _SCENES[name](ar_cfg)
