"""Checks of a map file before anything in it is used (``map_file.load_map``).

First the archive's members, from their ``.npy`` headers only: each array's dtype and shape, and its byte size
against the bytes the member really holds, so a header claiming a huge shape never allocates anything. Then the
shapes against each other and against the file's camera, and, once loaded, the values: finite numbers, rigid
keyframe poses, positive scene depths, unit normals, unit and perpendicular edgelet axes, every keyframe / point /
edgelet index and pyramid level in range, pixel positions inside the image, one measurement per (keyframe, point)
and per (keyframe, edgelet). Each problem is one :class:`InputError` line naming the file and the field. Checks are
vectorised: a map holds ~10^5 points.
"""

from __future__ import annotations

import math
import os
import zipfile
from dataclasses import dataclass
from typing import IO

import numpy as np

from ..errors import InputError
from .map import SRC_REFIND, SRC_ROOT

# Member (without ``.npy``) -> (dtype: "f" float, "iu" integer, "b" bool, "U" text, "B" uint8; shape), where a
# letter stands for a size: n keyframes, m points, k measurements, e edgelets, j edgelet measurements, H x W the
# camera's image.
FIELDS: dict[str, tuple[str, tuple]] = {
    "format": ("U", ()),
    "version": ("iu", ()),
    "camera": ("U", ()),
    "levels": ("iu", ()),
    "kf_image0": ("B", ("n", "H", "W")),
    "kf_T_cw": ("f", ("n", 4, 4)),
    "kf_depth_mean": ("f", ("n",)),
    "kf_depth_sigma": ("f", ("n",)),
    "kf_timestamp": ("f", ("n",)),
    "kf_panorama": ("b", ("n",)),
    "kf_part": ("iu", ("n",)),  # Gauglitz et al. §5.3: 0, or the merged track a keyframe came with (version 4)
    "X": ("f", ("m", 3)),
    "normal": ("f", ("m", 3)),
    "source_kf": ("iu", ("m",)),
    "source_level": ("iu", ("m",)),
    "source_xy": ("f", ("m", 2)),
    "bad": ("b", ("m",)),
    "ray": ("b", ("m",)),
    "meas_kf": ("iu", ("k",)),
    "meas_pt": ("iu", ("k",)),
    "meas_xy": ("f", ("k", 2)),
    "meas_level": ("iu", ("k",)),
    "meas_source": ("iu", ("k",)),
    # Agility §4: edgelets (centre, unit direction, unit dark-to-light normal, source keyframe, bad) and their
    # keyframe measurements, image lines a + λb (version 3).
    "edgelet_centre": ("f", ("e", 3)),
    "edgelet_direction": ("f", ("e", 3)),
    "edgelet_normal": ("f", ("e", 3)),
    "edgelet_source_kf": ("iu", ("e",)),
    "edgelet_bad": ("b", ("e",)),
    "edgelet_meas_kf": ("iu", ("j",)),
    "edgelet_meas_edgelet": ("iu", ("j",)),
    "edgelet_meas_a": ("f", ("j", 2)),
    "edgelet_meas_b": ("f", ("j", 2)),
}
_KINDS = {"f": "a float array", "iu": "an integer array", "b": "a bool array", "U": "text", "B": "uint8 images"}

# Deflate cannot expand data by more than ~1032:1; a member claiming more is lying about its size.
_DEFLATE_MAX_RATIO = 1100
# Saved poses are rotations to float precision (R^T R = I within ~1e-14) and normals unit vectors (~1e-15).
_ROTATION_TOL = 1e-6
_UNIT_TOL = 1e-6
# Pixel centres are at integer coordinates (ARCHITECTURE.md): a position inside the image lies in
# [-0.5, W - 0.5] x [-0.5, H - 0.5].
_PIXEL_HALF = 0.5


@dataclass(frozen=True)
class Member:
    """One ``.npy`` member as its header describes it."""

    shape: tuple[int, ...]
    dtype: np.dtype


def read_members(path: str) -> dict[str, Member]:
    """The header of every member of the archive at ``path``; only headers are read.

    Refuses members whose header claims more data than the member holds, and members whose stated size the
    archive cannot back (larger than the file, or than deflate can expand to)."""
    real_size = os.path.getsize(path)
    members = {}
    with zipfile.ZipFile(path) as zf:
        for info in zf.infolist():
            name = info.filename.removesuffix(".npy")
            _check_zip_sizes(path, name, info, real_size)
            with zf.open(info) as f:
                shape, dtype, header_bytes = _npy_header(path, name, f)
            claimed = math.prod(shape) * dtype.itemsize
            if claimed > info.file_size - header_bytes:
                raise InputError(
                    f"map file {path}: '{name}' claims shape {shape} of {dtype} ({claimed} bytes) but holds "
                    f"{info.file_size - header_bytes} bytes"
                )
            members[name] = Member(shape, dtype)
    return members


def _check_zip_sizes(path: str, name: str, info: zipfile.ZipInfo, real_size: int) -> None:
    if info.flag_bits & 0x1:
        raise InputError(f"map file {path}: '{name}' is encrypted")
    if info.compress_size > real_size:
        raise InputError(f"map file {path}: '{name}' claims {info.compress_size} bytes; the file has {real_size}")
    if info.compress_type == zipfile.ZIP_STORED:
        ok = info.file_size == info.compress_size
    elif info.compress_type == zipfile.ZIP_DEFLATED:
        ok = info.file_size <= _DEFLATE_MAX_RATIO * max(info.compress_size, 1)
    else:
        raise InputError(f"map file {path}: '{name}' uses zip compression method {info.compress_type}")
    if not ok:
        raise InputError(
            f"map file {path}: '{name}' claims {info.file_size} bytes from {info.compress_size} stored bytes"
        )


def _npy_header(path: str, name: str, f: IO[bytes]) -> tuple[tuple[int, ...], np.dtype, int]:
    """(shape, dtype, header length) of the ``.npy`` stream ``f``."""
    try:
        version = np.lib.format.read_magic(f)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(f)
        elif version == (2, 0):
            shape, _, dtype = np.lib.format.read_array_header_2_0(f)
        else:
            raise ValueError(f"unsupported .npy format version {version}")
    except ValueError as e:
        raise InputError(f"map file {path}: '{name}' is not a NumPy array ({e})") from None
    if dtype.hasobject:
        raise InputError(f"map file {path}: '{name}' holds Python objects")
    if any(d < 0 for d in shape):
        raise InputError(f"map file {path}: '{name}' has negative shape {shape}")
    return tuple(shape), dtype, f.tell()


def _dtype_ok(dtype: np.dtype, kinds: str) -> bool:
    return dtype == np.uint8 if kinds == "B" else dtype.kind in kinds


def check_layout(path: str, members: dict[str, Member], width: int, height: int) -> None:
    """Every field present with its dtype and a shape consistent with the others and the ``width`` x ``height``
    camera; at least one keyframe."""
    for name, (kinds, template) in FIELDS.items():
        if name not in members:
            raise InputError(f"map file {path} is incomplete: no '{name}'")
        m = members[name]
        if not _dtype_ok(m.dtype, kinds):
            raise InputError(f"map file {path}: '{name}' must be {_KINDS[kinds]}, got dtype {m.dtype}")
        if len(m.shape) != len(template):
            raise InputError(f"map file {path}: '{name}' must be {len(template)}-D, got shape {m.shape}")
    sizes = {
        "n": members["kf_image0"].shape[0],
        "m": members["X"].shape[0],
        "k": members["meas_kf"].shape[0],
        "e": members["edgelet_centre"].shape[0],
        "j": members["edgelet_meas_kf"].shape[0],
        "H": height,
        "W": width,
    }
    for name, (_, template) in FIELDS.items():
        expected = tuple(sizes[d] if isinstance(d, str) else d for d in template)
        if members[name].shape != expected:
            raise InputError(
                f"map file {path}: '{name}' has shape {members[name].shape}, expected {expected} "
                f"({sizes['n']} keyframes, {sizes['m']} points, {sizes['k']} measurements, {sizes['e']} edgelets, "
                f"{sizes['j']} edgelet measurements, {width}x{height} images)"
            )
    if sizes["n"] == 0:
        raise InputError(f"map file {path}: no keyframes")


def scalar(path: str, a: np.ndarray, name: str, kinds: str):
    """The value of a 0-d member of dtype ``kinds`` ("iu" or "U")."""
    if a.ndim != 0 or not _dtype_ok(a.dtype, kinds):
        what = "integer" if kinds == "iu" else "string"
        raise InputError(f"map file {path}: '{name}' must be a single {what}, got {a.dtype} of shape {a.shape}")
    return a.item()


def check_values(path: str, a: dict[str, np.ndarray], width: int, height: int, levels: int) -> None:
    """The loaded arrays (layout already checked) hold a usable map for a ``levels``-level pyramid."""
    for name, (kinds, _) in FIELDS.items():
        if kinds == "f":
            _finite(path, name, a[name])
    _rigid(path, a["kf_T_cw"])
    _rows_where(path, "kf_depth_mean", a["kf_depth_mean"] <= 0, a["kf_depth_mean"], "must be positive")
    _rows_where(path, "kf_depth_sigma", a["kf_depth_sigma"] < 0, a["kf_depth_sigma"], "must not be negative")
    _rows_where(path, "kf_part", a["kf_part"] < 0, a["kf_part"], "must not be negative")
    unit = np.abs(np.linalg.norm(a["normal"], axis=1) - 1.0) > _UNIT_TOL
    _rows_where(path, "normal", unit, a["normal"], "must be a unit vector")
    n, m = len(a["kf_image0"]), len(a["X"])
    for name, what, size in (("source_kf", "keyframe", n), ("meas_kf", "keyframe", n), ("meas_pt", "point", m)):
        _index(path, name, what, a[name], size)
    for name in ("source_level", "meas_level"):
        lv = a[name]
        if lv.size and (lv.min() < 0 or lv.max() >= levels):
            raise InputError(
                f"map file {path}: '{name}' holds pyramid level {lv.min() if lv.min() < 0 else lv.max()}; "
                f"the map's pyramid has levels 0..{levels - 1}"
            )
    src = a["meas_source"]
    if src.size and (src.min() < SRC_ROOT or src.max() > SRC_REFIND):
        raise InputError(
            f"map file {path}: 'meas_source' must be {SRC_ROOT}..{SRC_REFIND}, got {src.min()}..{src.max()}"
        )
    for name in ("source_xy", "meas_xy", "edgelet_meas_a"):
        xy = a[name]
        lo, hi = -_PIXEL_HALF, np.array([width, height]) - _PIXEL_HALF
        _rows_where(path, name, np.any((xy < lo) | (xy > hi), axis=1), xy, f"lies outside the {width}x{height} image")
    _unique_measurements(path, a["meas_kf"], a["meas_pt"], m)
    _check_edgelets(path, a, n)


def _check_edgelets(path: str, a: dict[str, np.ndarray], n: int) -> None:
    """Unit, perpendicular edgelet directions and normals (E-frame z and x, Agility §4.1), unit measured line
    directions, indices in range, one measurement per (keyframe, edgelet)."""
    for name in ("edgelet_direction", "edgelet_normal", "edgelet_meas_b"):
        unit = np.abs(np.linalg.norm(a[name], axis=1) - 1.0) > _UNIT_TOL
        _rows_where(path, name, unit, a[name], "must be a unit vector")
    dot = np.abs(np.sum(a["edgelet_direction"] * a["edgelet_normal"], axis=1)) > _UNIT_TOL
    _rows_where(path, "edgelet_normal", dot, a["edgelet_normal"], "must be perpendicular to 'edgelet_direction'")
    e = len(a["edgelet_centre"])
    for name, what, size in (
        ("edgelet_source_kf", "keyframe", n),
        ("edgelet_meas_kf", "keyframe", n),
        ("edgelet_meas_edgelet", "edgelet", e),
    ):
        _index(path, name, what, a[name], size)
    _unique_measurements(
        path, a["edgelet_meas_kf"], a["edgelet_meas_edgelet"], e, ("edgelet_meas_kf", "edgelet_meas_edgelet", "edgelet")
    )


def _finite(path: str, name: str, x: np.ndarray) -> None:
    bad = ~np.isfinite(x)
    if bad.any():
        i = np.unravel_index(int(np.argmax(bad)), x.shape)
        where = f"[{', '.join(map(str, i))}]" if x.ndim else ""
        raise InputError(f"map file {path}: '{name}{where}' is {x[i]}: every value must be finite")


def _rows_where(path: str, name: str, bad: np.ndarray, x: np.ndarray, problem: str) -> None:
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"map file {path}: '{name}[{i}]' = {x[i].tolist()} {problem}")


def _rigid(path: str, T: np.ndarray) -> None:
    R = T[:, :3, :3]
    err = np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2))
    bad = (err > _ROTATION_TOL) | (np.linalg.det(R) < 0) | np.any(T[:, 3] != [0.0, 0.0, 0.0, 1.0], axis=1)
    if bad.any():
        raise InputError(f"map file {path}: 'kf_T_cw[{int(np.argmax(bad))}]' is not a rigid transform")


def _index(path: str, name: str, what: str, idx: np.ndarray, size: int) -> None:
    # The wording "inconsistent: map: ... index out of range" is Map's own (map.py), kept for the same problem.
    if idx.size and (idx.min() < 0 or idx.max() >= size):
        raise InputError(
            f"map file {path} is inconsistent: map: {what} index out of range [0, {size}) in '{name}': "
            f"{idx.min()}..{idx.max()}"
        )


def _unique_measurements(
    path: str, kf: np.ndarray, pt: np.ndarray, n_points: int, names=("meas_kf", "meas_pt", "point")
) -> None:
    key = kf.astype(np.int64) * max(n_points, 1) + pt.astype(np.int64)
    order = np.argsort(key, kind="stable")
    same = key[order][1:] == key[order][:-1]
    if same.any():
        j = order[int(np.argmax(same)) + 1]
        raise InputError(
            f"map file {path}: '{names[0]}'/'{names[1]}': keyframe {kf[j]} measures {names[2]} {pt[j]} more than "
            f"once (measurement {j})"
        )
