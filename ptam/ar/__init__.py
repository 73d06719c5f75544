"""Augmented reality on the map's dominant plane (PTAM §6.1, §7.5): plane, scenes, rendering through the
real camera model, and the overlay attached to a running system (``attach``)."""

from .augmenter import Augmenter
from .layer import ArLayer, attach
from .plane import ArPlane
from .renderer import Renderer
from .scenes import SCENES, make_scene

__all__ = ["Augmenter", "ArLayer", "ArPlane", "Renderer", "SCENES", "attach", "make_scene"]
