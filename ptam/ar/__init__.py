"""Augmented reality on the map's dominant plane (PTAM §6.1, §7.5): plane, scenes, rendering through the
real camera model, and the overlay attached to a running system (``attach``)."""

from .ar_plane import ArPlane
from .augmenter import Augmenter
from .layer import ArLayer, attach
from .overlay import OverlayRenderer
from .scenes import SCENES, make_scene

__all__ = ["Augmenter", "ArLayer", "ArPlane", "OverlayRenderer", "SCENES", "attach", "make_scene"]
