"""Deterministic procedural textures for scene rectangles.

``dead_leaves``: the dead-leaves model — random rectangles, triangles and ellipses painted over each other
in random order, with radii drawn from a power law ``p(r) ∝ r^-exponent`` between ``sizes[0]`` and
``sizes[1]`` (metres) and grey levels uniform in ``grey``. With exponent 3 the visible shapes are equally
frequent in every octave of size, so the texture has corners at every pyramid level and no repeating tile
that would make patches ambiguous. ``detail`` adds texel-scale band-limited noise (grey-level standard
deviation) so no region is perfectly flat. ``coverage`` is the mean number of shape layers over a point.

``constant``: one grey level (test scenes with sharp, measurable geometric edges).

``image``: a photograph (``file``: a greyscale image bundled in ``data/synthetic/textures/``, or a path),
``texel`` metres per texel. ``mode: tile`` (default) repeats the image at one image pixel per texel from
corner 0 (image row 0 along the rectangle's first edge, image column 0 down its second); ``mode: stretch``
resamples the whole image onto the rectangle (aspect ratio not kept) at ``texel`` metres per texel. ``grey:
[low, high]`` maps the image's 0..255 linearly onto low..high (a faded print); default [0, 255].

Everything is drawn from ``numpy.random.default_rng(seed)``, so the same spec gives the same texels.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError
from ..resources import resource_path

DEAD_LEAVES_DEFAULTS = {"grey": [20, 235], "coverage": 4.0, "exponent": 3.0, "detail": 0.0}
IMAGE_DEFAULTS = {"mode": "tile", "grey": [0, 255]}
IMAGE_MODES = ("tile", "stretch")
TEXTURE_DIR = "data/synthetic/textures"  # bundled photographs (see its README.md for sources and licences)
_IMAGE_FULL_SCALE = 255.0  # an 8-bit image's white, mapped onto grey[1]
_SUBPIXEL_BITS = 4  # fixed-point vertex precision handed to OpenCV's polygon filler
_BATCH = 65536  # shapes drawn from the generator per round until the coverage is reached
_ASPECT_MIN = 0.25  # thinnest rectangle / ellipse (minor / major axis)
_DETAIL_BLUR_TEXELS = 1.0  # correlation length of the fine detail
_MAX_TEXELS = 64_000_000  # per texture; beyond this a scene file asks for gigabytes
_TRI_AREA = 3.0 * math.sqrt(3.0) / 4.0  # area / r² of an equilateral triangle, for the coverage count
_TRI_JITTER = 0.3  # triangle vertex angles vary by up to this fraction of a third of a turn


def _number(spec, key, where, lo=-math.inf, hi=math.inf):
    v = spec.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not (lo <= v <= hi) or not math.isfinite(v):
        raise InputError(f"{where}: texture '{key}' must be a number in [{lo:g}, {hi:g}], got {v!r}")
    return float(v)


def _pair(spec, key, where, lo, hi):
    v = spec.get(key)
    if (
        not isinstance(v, (list, tuple))
        or len(v) != 2
        or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)
        or not (lo <= v[0] <= v[1] <= hi)
    ):
        raise InputError(
            f"{where}: texture '{key}' must be [low, high] with {lo:g} <= low <= high <= {hi:g}, got {v!r}"
        )
    return float(v[0]), float(v[1])


def check_texture(spec: dict, where: str) -> dict:
    """The texture spec with defaults filled in, validated (cheap: nothing is drawn, an image file is only
    located)."""
    if not isinstance(spec, dict) or "type" not in spec:
        raise InputError(f"{where}: texture must be a mapping with a 'type' (dead_leaves, constant or image)")
    kind = spec["type"]
    if kind == "constant":
        unknown = set(spec) - {"type", "value"}
        if unknown:
            raise InputError(f"{where}: unknown constant-texture key(s) {', '.join(sorted(unknown))}")
        return {"type": kind, "value": _number(spec, "value", where, 0.0, 255.0)}
    if kind == "image":
        return _check_image(spec, where)
    if kind != "dead_leaves":
        raise InputError(f"{where}: unknown texture type '{kind}' (expected dead_leaves, constant or image)")
    spec = {**DEAD_LEAVES_DEFAULTS, **spec}
    unknown = set(spec) - {"type", "seed", "texel", "sizes", *DEAD_LEAVES_DEFAULTS}
    if unknown:
        raise InputError(f"{where}: unknown dead_leaves key(s) {', '.join(sorted(unknown))}")
    seed = spec.get("seed")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InputError(f"{where}: texture 'seed' must be a non-negative integer, got {seed!r}")
    texel = _number(spec, "texel", where, 1e-4, 10.0)
    return {
        "type": kind,
        "seed": seed,
        "texel": texel,
        "sizes": _pair(spec, "sizes", where, texel, 1e3),
        "grey": _pair(spec, "grey", where, 0.0, 255.0),
        "coverage": _number(spec, "coverage", where, 0.1, 100.0),
        "exponent": _number(spec, "exponent", where, 0.0, 10.0),
        "detail": _number(spec, "detail", where, 0.0, 128.0),
    }


def image_path(file: str) -> Path:
    """An image texture's file: a bare name is a bundled texture if there is one; anything else is a path."""
    p = Path(file)
    if p.parent == Path("."):
        try:
            return resource_path(f"{TEXTURE_DIR}/{file}")
        except FileNotFoundError:
            pass
    return p


def _check_image(spec: dict, where: str) -> dict:
    spec = {**IMAGE_DEFAULTS, **spec}
    unknown = set(spec) - {"type", "file", "texel", *IMAGE_DEFAULTS}
    if unknown:
        raise InputError(f"{where}: unknown image-texture key(s) {', '.join(sorted(unknown))}")
    file = spec.get("file")
    if not isinstance(file, str) or not file:
        raise InputError(f"{where}: image texture needs a 'file' (a bundled texture name or a path)")
    if not image_path(file).is_file():
        raise InputError(f"{where}: image texture file '{file}' not found (bundled ones are in {TEXTURE_DIR}/)")
    if spec["mode"] not in IMAGE_MODES:
        raise InputError(f"{where}: image texture 'mode' must be one of {', '.join(IMAGE_MODES)}, got {spec['mode']!r}")
    return {
        "type": "image",
        "file": file,
        "texel": _number(spec, "texel", where, 1e-4, 10.0),
        "mode": spec["mode"],
        "grey": _pair(spec, "grey", where, 0.0, 255.0),
    }


def image_digest(spec: dict, where: str) -> str | None:
    """SHA-256 of an image texture's file (part of the scene hash, so an edited image renders anew); None for
    procedural textures."""
    spec = check_texture(spec, where)
    if spec["type"] != "image":
        return None
    return hashlib.sha256(image_path(spec["file"]).read_bytes()).hexdigest()


def make_texture(spec: dict, width_m: float, height_m: float, where: str) -> tuple[np.ndarray, float]:
    """Texels (rows along the rectangle's second axis) as float32 grey levels, and the texel size in metres."""
    spec = check_texture(spec, where)
    if spec["type"] == "constant":
        return np.full((1, 1), spec["value"], dtype=np.float32), max(width_m, height_m)
    W, H = math.ceil(width_m / spec["texel"]), math.ceil(height_m / spec["texel"])
    if W * H > _MAX_TEXELS:
        raise InputError(f"{where}: texture of {W}x{H} texels is too large; raise 'texel'")
    if spec["type"] == "image":
        return _image(spec, W, H, where), spec["texel"]
    return _dead_leaves(spec, W, H), spec["texel"]


def _image(spec: dict, W: int, H: int, where: str) -> np.ndarray:
    """W x H texels of the image, tiled from its top-left pixel or resampled (area-averaged when shrunk)."""
    img = cv2.imread(str(image_path(spec["file"])), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise InputError(f"{where}: cannot read image texture '{spec['file']}'")
    if spec["mode"] == "stretch":
        shrink = img.size > W * H
        tex = cv2.resize(img, (W, H), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_CUBIC)
    else:
        reps = (math.ceil(H / img.shape[0]), math.ceil(W / img.shape[1]))
        tex = np.tile(img, reps)[:H, :W]
    lo, hi = spec["grey"]
    return (np.float32(lo) + tex.astype(np.float32) * np.float32((hi - lo) / _IMAGE_FULL_SCALE)).astype(np.float32)


def _radii(u, lo, hi, exponent):
    """Inverse CDF of p(r) ∝ r^-exponent on [lo, hi]."""
    if abs(exponent - 1.0) < 1e-9:
        return lo * (hi / lo) ** u
    e = 1.0 - exponent
    return (lo**e + u * (hi**e - lo**e)) ** (1.0 / e)


def _dead_leaves(spec: dict, W: int, H: int) -> np.ndarray:
    texel = spec["texel"]
    (r_lo, r_hi), (g_lo, g_hi) = spec["sizes"], spec["grey"]
    coverage, exponent, detail = spec["coverage"], spec["exponent"], spec["detail"]
    rng = np.random.default_rng(spec["seed"])
    img = np.full((H, W), round(0.5 * (g_lo + g_hi)), dtype=np.uint8)
    target = coverage * W * H
    painted = 0.0
    while painted < target:
        leaf = _leaf_batch(rng, W, H, r_lo / texel, r_hi / texel, exponent, g_lo, g_hi)
        r, cx, cy = leaf.r, leaf.cx, leaf.cy
        area = np.where(leaf.kind == 0, 4.0 * leaf.aspect, np.where(leaf.kind == 1, _TRI_AREA, np.pi * leaf.aspect))
        inside = (np.minimum(cx + r, W) - np.maximum(cx - r, 0)) * (np.minimum(cy + r, H) - np.maximum(cy - r, 0))
        # only the part inside the texture counts as coverage
        csum = painted + np.cumsum(area * r * r * np.clip(inside / (4.0 * r * r), 0.0, 1.0))
        n = int(min(_BATCH, np.searchsorted(csum, target) + 1))
        painted = csum[n - 1]
        _paint_leaves(img, leaf, n)
    tex = img.astype(np.float32)
    if detail > 0:
        noise = cv2.GaussianBlur(rng.standard_normal((H, W)).astype(np.float32), (0, 0), _DETAIL_BLUR_TEXELS)
        tex += noise * np.float32(detail / max(float(noise.std()), 1e-12))
        np.clip(tex, 0.0, 255.0, out=tex)
    return tex


@dataclass
class _Leaves:
    r: np.ndarray
    aspect: np.ndarray
    kind: np.ndarray  # 0 rectangle, 1 triangle, 2 ellipse
    cx: np.ndarray
    cy: np.ndarray
    ang: np.ndarray
    tri: np.ndarray
    grey: np.ndarray


def _leaf_batch(rng, W: int, H: int, r_lo: float, r_hi: float, exponent: float, g_lo, g_hi) -> _Leaves:
    n = _BATCH
    r = _radii(rng.random(n), r_lo, r_hi, exponent)
    aspect = rng.uniform(_ASPECT_MIN, 1.0, n)
    kind = rng.integers(0, 3, n)
    # Centres may fall a radius outside the rectangle so the borders are covered as densely as the middle.
    cx = rng.uniform(-r, W + r)
    cy = rng.uniform(-r, H + r)
    ang = rng.uniform(0.0, 2.0 * np.pi, n)
    # Triangle vertices a third of a turn apart, jittered: irregular but never slivers.
    tri = ang[:, None] + (2.0 * np.pi / 3.0) * (np.arange(3) + rng.uniform(-_TRI_JITTER, _TRI_JITTER, (n, 3)))
    grey = rng.integers(round(g_lo), round(g_hi) + 1, n)
    return _Leaves(r, aspect, kind, cx, cy, ang, tri, grey)


def _paint_leaves(img: np.ndarray, leaf: _Leaves, n: int) -> None:
    """The first ``n`` leaves of the batch, in painter's order (the dead-leaves occlusion), at sub-pixel accuracy."""
    scale = 1 << _SUBPIXEL_BITS
    r, aspect, cx, cy, ang = leaf.r, leaf.aspect, leaf.cx, leaf.cy, leaf.ang
    ca, sa = np.cos(ang), np.sin(ang)
    corners = ((-1, -1), (1, -1), (1, 1), (-1, 1))
    rect = np.stack([np.stack([sx * r, sy * r * aspect], -1) for sx, sy in corners], axis=1)  # before rotation
    rect = np.stack(
        [
            ca[:, None] * rect[..., 0] - sa[:, None] * rect[..., 1],
            sa[:, None] * rect[..., 0] + ca[:, None] * rect[..., 1],
        ],
        axis=-1,
    )
    rect = np.round((rect + np.stack([cx, cy], -1)[:, None]) * scale).astype(np.int32)
    tri = leaf.tri
    tri_xy = np.stack([cx[:, None] + r[:, None] * np.cos(tri), cy[:, None] + r[:, None] * np.sin(tri)], axis=-1)
    tri_pts = np.round(tri_xy * scale).astype(np.int32)
    cen = np.round(np.stack([cx, cy], -1) * scale).astype(np.int32)
    axes = np.round(np.stack([r, r * aspect], -1) * scale).astype(np.int32)
    deg = np.degrees(ang)
    for i in range(n):  # one-off generation, not a per-frame path
        g = int(leaf.grey[i])
        if leaf.kind[i] == 0:
            cv2.fillConvexPoly(img, rect[i], g, cv2.LINE_8, _SUBPIXEL_BITS)
        elif leaf.kind[i] == 1:
            cv2.fillConvexPoly(img, tri_pts[i], g, cv2.LINE_8, _SUBPIXEL_BITS)
        else:
            cv2.ellipse(img, cen[i], axes[i], deg[i], 0.0, 360.0, g, -1, cv2.LINE_8, _SUBPIXEL_BITS)
