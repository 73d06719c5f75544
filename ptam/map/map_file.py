"""Map files: save a map and load it back (``ptam run --map FILE`` / ``--load-map FILE``).

A map file is a NumPy ``.npz`` archive (compressed, no pickles) named by a format string and a version. It holds
what cannot be recomputed: each keyframe's level-0 image, pose, depth statistics and timestamp, every point column
(bad points included, so indices stay valid), every measurement column, every edgelet and edgelet-measurement
column (version 3), the camera and the pyramid depth the map was built with. Everything derived (the other pyramid
levels, FAST corners, row tables, and whatever else a :class:`KeyFrame` builds from its image) is rebuilt on load
from the current config; so are the edgelets' visibility tables (Agility §5.2), by the mapper that takes the map.
Files are written to a temporary file in the target directory and renamed into place, so a crash never leaves half
a map behind.

Versions: 1 (points), 2 (+ panorama keyframes and rays, Gauglitz et al. §3.2), 3 (+ edgelets, Agility §4), 4 (+ the
merged track each keyframe came with, §5.3). Every older version is still read; what it cannot hold loads as
absent (no panoramas, no rays, no edgelets, every keyframe the map's own).
"""

from __future__ import annotations

import json
import os
import tempfile
import zipfile
import zlib
from dataclasses import dataclass

import numpy as np

from ..camera import camera_from_dict
from ..errors import InputError, PtamError
from ..image.pyramid import Pyramid
from .keyframe import KeyFrame
from .map import Map
from .map_file_checks import FIELDS, Member, check_layout, check_values, read_members, scalar
from .snapshot import MapSnapshot

FORMAT = "ptam-map"
VERSION = 4
# Version 2 added panorama keyframes and their rays (Gauglitz et al. §3.2); version 3 the edgelets and their
# keyframe measurements (Agility §4); version 4 the keyframes' merged-track parts (§5.3). An older map has none of
# what came later: field -> the field whose length it has (an empty field when that is itself new). Versions 1 to
# 3 are still read.
_ADDED = {
    2: {"ray": "X", "kf_panorama": "kf_image0"},
    3: {k: "" for k in FIELDS if k.startswith("edgelet_")},
    4: {"kf_part": "kf_image0"},
}

_POINTS = ("X", "normal", "source_kf", "source_level", "source_xy", "bad", "ray")
_MEASUREMENTS = ("meas_kf", "meas_pt", "meas_xy", "meas_level", "meas_source")
_EDGELETS = tuple(_ADDED[3])
_EMPTY_DTYPES = {"f": np.float64, "iu": np.int64, "b": np.bool_}


@dataclass(frozen=True)
class LoadedMap:
    """A map read from a file and the camera it was built with."""

    map: Map
    camera: object


def save_map(path: str | os.PathLike, snapshot: MapSnapshot, camera, levels: int) -> None:
    """Write ``snapshot`` (built with ``camera`` and a ``levels``-level pyramid) to ``path`` atomically."""
    path = os.fspath(path)
    if snapshot.n_keyframes == 0:
        raise PtamError(f"no map to write to {path}: it has no keyframes")
    arrays = {
        "format": np.array(FORMAT),
        "version": np.array(VERSION),
        "camera": np.array(json.dumps(camera.to_dict())),
        "levels": np.array(levels),
        "kf_image0": np.stack([kf.pyramid.levels[0] for kf in snapshot.keyframes]),
        "kf_T_cw": np.asarray(snapshot.kf_T_cw),
        "kf_depth_mean": np.array([kf.scene_depth_mean for kf in snapshot.keyframes]),
        "kf_depth_sigma": np.array([kf.scene_depth_sigma for kf in snapshot.keyframes]),
        "kf_timestamp": np.array([kf.timestamp for kf in snapshot.keyframes]),
        "kf_panorama": np.array([kf.panorama for kf in snapshot.keyframes], dtype=bool),
        "kf_part": np.array([kf.part for kf in snapshot.keyframes], dtype=np.int64),
        **{k: np.asarray(getattr(snapshot, k)) for k in _POINTS + _MEASUREMENTS + _EDGELETS},
    }
    directory = os.path.dirname(os.path.abspath(path))
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(path)}.", suffix=".tmp", dir=directory)
    except OSError as e:
        raise InputError(f"cannot write map file {path}: {e.strerror}") from None
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez_compressed(f, allow_pickle=False, **arrays)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except OSError as e:
        os.unlink(tmp)
        raise InputError(f"cannot write map file {path}: {e.strerror}") from None
    except BaseException:
        os.unlink(tmp)
        raise


def _read(path: str, image_cfg) -> tuple[dict[str, np.ndarray], object]:
    """The checked arrays of the map file at ``path`` and its camera: member headers, format, version, camera,
    pyramid depth and every field's dtype and shape are checked before the arrays are loaded, their values
    after (:mod:`map_file_checks`)."""
    if not os.path.isfile(path):
        raise InputError(f"map file not found: {path}")
    if not zipfile.is_zipfile(path):
        raise InputError(f"{path} is not a ptam map file (not an .npz archive, or truncated)")
    try:
        members = read_members(path)
        with np.load(path, allow_pickle=False) as z:
            version = _check_format(path, z, members)
            camera = _camera(path, z["camera"])
            levels = scalar(path, z["levels"], "levels", "iu")
            if levels != image_cfg.levels:
                raise InputError(
                    f"map file {path} was built with {levels} pyramid levels; the config has "
                    f"image.levels = {image_cfg.levels}"
                )
            stored = set(members)
            members = {**members, **_added_since(version, members)}
            check_layout(path, members, camera.width, camera.height)
            arrays = {k: z[k] if k in stored else np.zeros(members[k].shape, members[k].dtype) for k in FIELDS}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as e:
        raise InputError(f"cannot read map file {path}: corrupt or not a ptam map ({e})") from None
    check_values(path, arrays, camera.width, camera.height, levels)
    return arrays, camera


def _new_since(version: int) -> list[str]:
    """The fields a file of format ``version`` cannot have."""
    return [k for v, fields in _ADDED.items() if version < v for k in fields]


def _added_since(version: int, members: dict[str, Member]) -> dict[str, Member]:
    """Stand-ins for the fields a ``version`` file cannot have: false flags for panoramas and rays, no edgelets,
    part 0 (the map's own) for every keyframe."""
    out = {}
    for k in _new_since(version):
        like = next(f[k] for f in _ADDED.values() if k in f)
        kinds, template = FIELDS[k]
        shape = members[like].shape[:1] if like else (0, *template[1:])
        out[k] = Member(shape, np.dtype(_EMPTY_DTYPES[kinds]))
    return out


def _check_format(path: str, z, members: dict) -> int:
    """The format string and version (first: another version may hold other fields), then every field present;
    returns the version."""
    if "format" not in members or members["format"].dtype.kind != "U" or str(z["format"]) != FORMAT:
        raise InputError(f"{path} is not a ptam map file")
    v = members.get("version")
    version = int(z["version"]) if v is not None and v.dtype.kind in "iu" and v.shape == () else -1
    if version not in range(1, VERSION + 1):
        raise InputError(
            f"map file {path} has format version {version}; this ptam reads version {VERSION} (and 1 to 3)"
        )
    missing = [k for k in FIELDS if k not in members and k not in _new_since(version)]
    if missing:
        raise InputError(f"map file {path} is incomplete: no '{missing[0]}'")
    return version


def _camera(path: str, member: np.ndarray):
    try:
        record = json.loads(scalar(path, member, "camera", "U"))
    except json.JSONDecodeError:
        raise InputError(f"map file {path}: unreadable camera record") from None
    return camera_from_dict(record, where=f"map file {path}: camera")


def load_map(path: str | os.PathLike, image_cfg) -> LoadedMap:
    """Read a map file written by :func:`save_map`; keyframe pyramids are rebuilt with ``image_cfg``.

    Any problem with the file (missing, corrupt, another format or version, a wrong dtype or shape, a size its
    archive cannot back, non-finite values, an index or level out of range, duplicate measurements, a pyramid
    depth other than ``image_cfg.levels``) raises :class:`InputError` naming the file and the field; the checks
    (:mod:`map_file_checks`) run before anything is built from the file."""
    path = os.fspath(path)
    a, camera = _read(path, image_cfg)
    m = Map()
    try:
        for i, image in enumerate(a["kf_image0"]):
            pyramid = Pyramid.build(image, image_cfg)
            depth, sigma, stamp = (float(a[k][i]) for k in ("kf_depth_mean", "kf_depth_sigma", "kf_timestamp"))
            kf = KeyFrame(i, pyramid, depth, sigma, stamp, bool(a["kf_panorama"][i]), int(a["kf_part"][i]))
            m.add_keyframe(kf, a["kf_T_cw"][i])
        m.add_points(a["X"], a["normal"], a["source_kf"], a["source_level"], a["source_xy"], a["ray"])
        if a["bad"].any():
            m.mark_bad(np.flatnonzero(a["bad"]))
        m.add_measurements(a["meas_kf"], a["meas_pt"], a["meas_xy"], a["meas_level"], a["meas_source"])
        _load_edgelets(m, a)
    except PtamError as e:
        raise InputError(f"map file {path} is inconsistent: {e}") from None
    return LoadedMap(m, camera)


def _load_edgelets(m: Map, a: dict[str, np.ndarray]) -> None:
    """Agility §4: the edgelets and their measurements; visibility tables (§5.2) are derived and rebuilt by the
    mapper from the keyframe images and these measurements."""
    if len(a["edgelet_centre"]):
        m.add_edgelets(a["edgelet_centre"], a["edgelet_direction"], a["edgelet_normal"], a["edgelet_source_kf"])
        if a["edgelet_bad"].any():
            m.mark_edgelets_bad(np.flatnonzero(a["edgelet_bad"]))
    if len(a["edgelet_meas_kf"]):
        m.add_edgelet_measurements(
            a["edgelet_meas_kf"], a["edgelet_meas_edgelet"], a["edgelet_meas_a"], a["edgelet_meas_b"]
        )
