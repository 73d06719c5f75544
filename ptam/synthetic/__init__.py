"""Synthetic sequences with exact ground truth: PTAM §7.3's two-wall scene and others.

Scenes are YAML files of textured rectangles, a camera and key poses (``data/synthetic/*.yaml``); frames
are ray-cast through the camera model. ``load_scene`` gives poses and per-pixel geometry; ``ensure_sequence``
renders a scene once into the cache in TUM RGB-D layout.
"""

from .scene import Scene, load_scene
from .sequence import ensure_sequence, write_sequence
from .spec import list_scenes

__all__ = ["Scene", "load_scene", "ensure_sequence", "write_sequence", "list_scenes"]
