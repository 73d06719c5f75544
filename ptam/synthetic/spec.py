"""Scene files: locating bundled scenes by name, reading YAML, resolving ``extends``, hashing.

A scene file may start from another one with ``extends: NAME`` (a file next to it or a bundled scene) and
override parts of it: mappings merge key by key, anything else (lists, numbers) replaces the base value, but
``more_rectangles`` is appended to the base's ``rectangles`` (drawn after them), so a variant adds objects
without repeating the base's.
The resolved description is what a rendered sequence is keyed by (``scene_hash``) and what is written as
``scene.yaml`` next to it, so the output is reproducible from that file alone.
"""

from __future__ import annotations

import copy
import hashlib
import json
from pathlib import Path

import yaml

from ..errors import InputError
from ..resources import resource_path

# Bump when the renderer or texture generator changes what a scene file renders to (invalidates caches).
RENDER_VERSION = 4
_MAX_EXTENDS_DEPTH = 8
# The accuracy suite: desk-scale scenes unlike two_wall (pinhole and radtan lenses, photographs, repetitive
# and plain surfaces, hand-held jitter, pauses, brightness changes, sensor noise, a 90 degree turn, 15 fps).
SUITE = ("desk_table", "desk_table_15fps", "desk_bricks", "desk_corner", "desk_closeup")


def _bundled_dir() -> Path:
    return resource_path("data/synthetic")


def list_scenes() -> list[str]:
    """Names of the bundled scenes (``data/synthetic/*.yaml``)."""
    return sorted(p.stem for p in _bundled_dir().glob("*.yaml"))


def suite_scenes() -> list[str]:
    """The accuracy suite (``ptam bench accuracy suite``), in table order."""
    return list(SUITE)


def locate_scene(name_or_path: str | Path, relative_to: Path | None = None) -> Path:
    """A scene file: an existing path, a file next to ``relative_to``, or a bundled scene name."""
    s = str(name_or_path)
    candidates = [Path(s)]
    if relative_to is not None:
        candidates.append(relative_to / s)
        candidates.append(relative_to / f"{s}.yaml")
    if "/" not in s and "\\" not in s:
        candidates.append(_bundled_dir() / (s if s.endswith(".yaml") else f"{s}.yaml"))
    for c in candidates:
        if c.is_file():
            return c
    raise InputError(f"unknown scene '{s}': not a file and not a bundled scene ({', '.join(list_scenes())})")


def _read(path: Path) -> dict:
    try:
        with open(path) as f:
            d = yaml.safe_load(f)
    except (OSError, yaml.YAMLError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read scene {path}: {str(e).splitlines()[0]}") from None
    if not isinstance(d, dict):
        raise InputError(f"scene {path}: expected a mapping at the top level")
    return d


def _merge(base: dict, over: dict) -> dict:
    out = copy.deepcopy(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else copy.deepcopy(v)
    return out


def resolve_scene(name_or_path: str | Path) -> tuple[str, dict, Path]:
    """(name, resolved description, file) for a scene file or bundled name."""
    path = locate_scene(name_or_path)
    d = _read(path)
    seen = [path.resolve()]
    while "extends" in d:
        if len(seen) > _MAX_EXTENDS_DEPTH:
            raise InputError(f"scene {path}: 'extends' chain longer than {_MAX_EXTENDS_DEPTH}")
        base_path = locate_scene(str(d["extends"]), relative_to=seen[-1].parent)
        if base_path.resolve() in seen:
            raise InputError(f"scene {path}: 'extends' loops back to {base_path}")
        seen.append(base_path.resolve())
        over = {k: v for k, v in d.items() if k not in ("extends", "more_rectangles")}
        more = d.get("more_rectangles", [])
        if not isinstance(more, list):
            raise InputError(f"scene {path}: 'more_rectangles' must be a list of rectangles")
        d = _merge(_read(base_path), over)
        if more:
            d["rectangles"] = [*(d.get("rectangles") or []), *copy.deepcopy(more)]
    return path.stem, d, path


def scene_hash(resolved: dict, texture_files: dict[str, str] | None = None) -> str:
    """Hex digest keying a rendered sequence: the resolved scene content, the renderer version and, for scenes
    with image textures, the digests of their files (``texture_files``; absent for procedural scenes, so
    their hashes do not change)."""
    content: dict = {"scene": resolved, "render_version": RENDER_VERSION}
    if texture_files:
        content["texture_files"] = texture_files
    blob = json.dumps(content, sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]
