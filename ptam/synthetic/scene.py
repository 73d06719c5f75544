"""A synthetic scene: camera, textured rectangles, trajectory and image effects, with exact ground truth.

Scene file layout (YAML; see ``data/synthetic/two_wall.yaml``)::

    camera: {model: fov, width: 640, height: 480, fx: ..., fy: ..., cx: ..., cy: ..., omega: ...}
    frames: 600                    # number of frames
    fps: 30
    start_time: 0.0                # timestamp of frame 0 (s), optional
    rectangles:                    # see ptam/synthetic/rectangle.py and texture.py
      - {name: wall1, corners: [[x, y, z], ...], texture: {type: dead_leaves, seed: 1, texel: 0.005, ...}}
    trajectory:
      up: [0, 0, 1]                # world up, keeps the camera upright
      keys:                        # key poses; optional roll_deg, and hold (frames at rest on the pose)
        - {frame: 0, position: [x, y, z], look_at: [x, y, z]}
      jitter: {seed: 5, position_m: 0.002, rotation_deg: 0.1, frequency_hz: [0.3, 2.0], components: 6}
    render:                        # every key optional
      supersample: 2               # n x n samples per pixel
      background: 0                # grey level of rays that hit nothing
      optics_blur_px: 1.0          # Gaussian point-spread function of lens and sensor (sigma, pixels)
      noise: {sigma: 2.0, seed: 1}                  # additive Gaussian pixel noise (grey levels)
      motion_blur: {subframes: 4, exposure: 0.5}    # exposure as a fraction of the frame interval, centred;
                                                    # max_step_px (default 1): fewer sub-frames where the image
                                                    # moves less (ptam/synthetic/motion_blur.py), 0: always all
      brightness: {amplitude: 0.05, period_s: 8.0}  # gain 1 + A·sin(2π t / period)
      black_frames: [[300, 309]]                    # inclusive frame ranges rendered black

The ground-truth pose of a frame is the camera at its timestamp (the middle of the exposure).
"""

from __future__ import annotations

import math
import threading
from pathlib import Path

import cv2
import numpy as np

from ..camera import camera_from_dict
from ..errors import InputError
from .motion_blur import probe_pixels, smear_px, subframe_count
from .rectangle import Rectangle, rectangle_from_spec
from .render import Renderer
from .render_kernels import intersect_rays
from .spec import resolve_scene, scene_hash
from .texture import check_texture, image_digest
from .trajectory import Jitter, KeyPose, Trajectory, look_at, path_length

RENDER_DEFAULTS = {"supersample": 2, "background": 0.0}
BLUR_STEP_PX = 1.0  # motion_blur.max_step_px: sub-frames a pixel apart draw a continuous smear
_TOP_KEYS = {"description", "camera", "frames", "fps", "start_time", "rectangles", "trajectory", "render"}
_RENDER_KEYS = {"supersample", "background", "optics_blur_px", "noise", "motion_blur", "brightness", "black_frames"}


def _num(d: dict, key: str, where: str, lo=-math.inf, hi=math.inf, default=None, integer=False):
    if key not in d:
        if default is None:
            raise InputError(f"{where}: missing '{key}'")
        return default
    v = d[key]
    ok = (
        not isinstance(v, bool)
        and isinstance(v, (int, float))
        and math.isfinite(v)
        and lo <= v <= hi
        and (not integer or v == int(v))
    )
    if not ok:
        kind = "an integer" if integer else "a number"
        raise InputError(f"{where}: '{key}' must be {kind} in [{lo:g}, {hi:g}], got {v!r}")
    return int(v) if integer else float(v)


def _mapping(d, key, where, allowed):
    v = d.get(key, {})
    if not isinstance(v, dict):
        raise InputError(f"{where}: '{key}' must be a mapping")
    unknown = set(v) - set(allowed)
    if unknown:
        raise InputError(f"{where}.{key}: unknown key(s) {', '.join(sorted(map(str, unknown)))}")
    return v


def _vec3(v, where):
    a = np.asarray(v, dtype=np.float64) if isinstance(v, (list, tuple)) else None
    if a is None or a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InputError(f"{where}: expected a list of 3 numbers, got {v!r}")
    return a


def _trajectory(d: dict, fps: float, where: str) -> Trajectory:
    t = _mapping(d, "trajectory", where, {"up", "keys", "jitter"})
    where = f"{where}.trajectory"
    up = _vec3(t.get("up", [0, 0, 1]), f"{where}.up")
    keys = t.get("keys")
    if not isinstance(keys, list) or len(keys) < 2:
        raise InputError(f"{where}: 'keys' must list at least two key poses")
    poses, last = [], -math.inf
    for i, k in enumerate(keys):
        w = f"{where}.keys[{i}]"
        if not isinstance(k, dict):
            raise InputError(f"{w}: a key pose must be a mapping")
        unknown = set(k) - {"frame", "position", "look_at", "roll_deg", "hold"}
        if unknown:
            raise InputError(f"{w}: unknown key(s) {', '.join(sorted(unknown))}")
        frame = _num(k, "frame", w, lo=0.0)
        hold = _num(k, "hold", w, lo=0.0, default=0.0)
        if frame <= last:
            raise InputError(f"{w}: key frames must increase (and come after the previous hold)")
        last = frame + hold
        pos = _vec3(k.get("position"), f"{w}.position")
        target = _vec3(k.get("look_at"), f"{w}.look_at")
        f = target - pos
        if np.linalg.norm(f) < 1e-9 or np.linalg.norm(np.cross(f, up)) < 1e-9 * np.linalg.norm(f):
            raise InputError(f"{w}: look_at must differ from position and not be straight up or down")
        roll = math.radians(_num(k, "roll_deg", w, default=0.0))
        poses.append(KeyPose(frame, pos, look_at(pos, target, up, roll), hold))
    jitter = None
    if "jitter" in t:
        j = _mapping(t, "jitter", where, {"seed", "position_m", "rotation_deg", "frequency_hz", "components"})
        wj = f"{where}.jitter"
        fr = j.get("frequency_hz")
        if not (
            isinstance(fr, list)
            and len(fr) == 2
            and all(isinstance(x, (int, float)) for x in fr)
            and 0 < fr[0] <= fr[1]
        ):
            raise InputError(f"{wj}: 'frequency_hz' must be [low, high] with 0 < low <= high")
        jitter = Jitter(
            seed=_num(j, "seed", wj, lo=0, integer=True),
            position_m=_num(j, "position_m", wj, lo=0.0),
            rotation_rad=math.radians(_num(j, "rotation_deg", wj, lo=0.0)),
            freq_lo_hz=float(fr[0]),
            freq_hi_hz=float(fr[1]),
            components=_num(j, "components", wj, lo=1, integer=True),
        )
    return Trajectory(poses, jitter, fps)


def _texture_files(rects: list[Rectangle], where: str) -> dict[str, str]:
    """Digest of every image texture's file by rectangle index (empty for procedural scenes)."""
    digests = ((i, image_digest(r.texture, f"{where}.rectangles[{i}]")) for i, r in enumerate(rects))
    return {str(i): d for i, d in digests if d is not None}


class Scene:
    """A loaded scene. Ground truth: ``timestamps`` (N,), ``poses_T_wc`` (N, 4, 4), ``raycast``."""

    def __init__(self, name: str, spec: dict, source: Path | None = None):
        where = f"scene {name}"
        unknown = set(spec) - _TOP_KEYS
        if unknown:
            raise InputError(f"{where}: unknown key(s) {', '.join(sorted(map(str, unknown)))}")
        self.name = name
        self.spec = spec
        self.source = source
        if "camera" not in spec:
            raise InputError(f"{where}: missing 'camera'")
        self.camera = camera_from_dict(spec["camera"], where=f"{where}.camera")
        self.n_frames = _num(spec, "frames", where, lo=1, integer=True)
        self.fps = _num(spec, "fps", where, lo=1e-3)
        start = _num(spec, "start_time", where, lo=0.0, default=0.0)
        self.timestamps = start + np.arange(self.n_frames) / self.fps
        rects = spec.get("rectangles")
        if not isinstance(rects, list) or not rects:
            raise InputError(f"{where}: 'rectangles' must be a non-empty list")
        self.rectangles: list[Rectangle] = [
            rectangle_from_spec(r, f"{where}.rectangles[{i}]") for i, r in enumerate(rects)
        ]
        for i, r in enumerate(self.rectangles):
            check_texture(r.texture, f"{where}.rectangles[{i}]")
        self.hash = scene_hash(spec, _texture_files(self.rectangles, where))
        self._packed = np.stack([r.packed() for r in self.rectangles])
        self.trajectory = _trajectory(spec, self.fps, where)
        if self.n_frames - 1 > self.trajectory.last_frame:
            raise InputError(
                f"{where}: the trajectory's keys end at frame {self.trajectory.last_frame:g} "
                f"but the scene has {self.n_frames} frames"
            )
        self.poses_T_wc = self.trajectory.poses(np.arange(self.n_frames, dtype=np.float64))
        self._read_render(spec, where)
        self._renderer = None
        self._probe_uv = probe_pixels(self.camera)
        self._lock = threading.Lock()

    def _read_render(self, spec: dict, where: str) -> None:
        """The ``render`` section: supersampling, background, lens blur, noise, motion blur, brightness, black
        frames."""
        r = _mapping(spec, "render", where, _RENDER_KEYS)
        wr = f"{where}.render"
        self.supersample = _num(r, "supersample", wr, lo=1, hi=8, integer=True, default=RENDER_DEFAULTS["supersample"])
        self.background = _num(r, "background", wr, lo=0.0, hi=255.0, default=RENDER_DEFAULTS["background"])
        self.optics_blur = _num(r, "optics_blur_px", wr, lo=0.0, hi=10.0, default=0.0)
        noise = _mapping(r, "noise", wr, {"sigma", "seed"})
        self.noise_sigma = _num(noise, "sigma", f"{wr}.noise", lo=0.0, default=0.0)
        self.noise_seed = _num(noise, "seed", f"{wr}.noise", lo=0, integer=True, default=0)
        blur = _mapping(r, "motion_blur", wr, {"subframes", "exposure", "max_step_px"})
        self.blur_subframes = _num(blur, "subframes", f"{wr}.motion_blur", lo=1, hi=64, integer=True, default=1)
        self.blur_exposure = _num(blur, "exposure", f"{wr}.motion_blur", lo=0.0, hi=1.0, default=0.0)
        self.blur_step_px = _num(blur, "max_step_px", f"{wr}.motion_blur", lo=0.0, default=BLUR_STEP_PX)
        bright = _mapping(r, "brightness", wr, {"amplitude", "period_s"})
        self.brightness_amplitude = _num(bright, "amplitude", f"{wr}.brightness", lo=0.0, hi=1.0, default=0.0)
        self.brightness_period = _num(bright, "period_s", f"{wr}.brightness", lo=1e-3, default=1.0)
        self.black = np.zeros(self.n_frames, dtype=bool)
        black = r.get("black_frames", [])
        if not isinstance(black, list):
            raise InputError(f"{wr}: 'black_frames' must be a list of [first, last] frame ranges")
        for rng in black:
            if (
                not isinstance(rng, list)
                or len(rng) != 2
                or not all(isinstance(x, int) for x in rng)
                or not 0 <= rng[0] <= rng[1]
            ):
                raise InputError(f"{wr}: black_frames entry {rng!r} must be [first, last] frame numbers")
            self.black[rng[0] : rng[1] + 1] = True

    def prepare(self) -> Renderer:
        """The renderer, built on first use: textures take a few seconds; rendering threads then only read."""
        with self._lock:
            if self._renderer is None:
                self._renderer = Renderer(self.camera, self.rectangles, self.supersample, self.background)
            return self._renderer

    @property
    def renderer(self) -> Renderer:
        return self.prepare()

    @property
    def path_length(self) -> float:
        return path_length(self.poses_T_wc)

    def subframe_poses(self, i: int) -> np.ndarray:
        """T_wc (P, 4, 4) of the motion-blur sub-frames of frame i, spread evenly over the exposure: as many as its
        image motion needs (``motion_blur``), at most ``subframes``."""
        P = self.blur_subframes
        if P == 1 or self.blur_exposure == 0.0:
            return self.poses_T_wc[i : i + 1]
        full = self.trajectory.poses(i + (np.arange(P) / (P - 1) - 0.5) * self.blur_exposure)
        if self.blur_step_px == 0.0:
            return full
        X, _, hit = self.raycast(self.poses_T_wc[i], self._probe_uv)
        smear = smear_px(self.camera, X[hit], full)
        n = subframe_count(smear, self.blur_step_px, P)
        if n == P:
            return full
        if n == 1:
            return self.poses_T_wc[i : i + 1]
        return self.trajectory.poses(i + (np.arange(n) / (n - 1) - 0.5) * self.blur_exposure)

    def render_view(self, poses_T_wc: np.ndarray) -> np.ndarray:
        """Noise-free float32 (H, W) image seen from the sub-frame poses (P, 4, 4), through the optics."""
        img = self.renderer.render(poses_T_wc)
        if self.optics_blur > 0:
            # A real camera's lens and sensor never image a step edge as a step; without this PSF every
            # edge is a perfect anti-aliased step and patch SSDs react to a tenth of a pixel.
            img = cv2.GaussianBlur(img, (0, 0), self.optics_blur, borderType=cv2.BORDER_REPLICATE)
        return img

    def render_frame(self, i: int) -> np.ndarray:
        """Frame i as uint8 (H, W), with the scene's blur, brightness drift, noise and black frames applied."""
        if not 0 <= i < self.n_frames:
            raise InputError(f"scene {self.name}: frame {i} out of range 0..{self.n_frames - 1}")
        if self.black[i]:
            return np.zeros((self.camera.height, self.camera.width), dtype=np.uint8)
        img = self.render_view(self.subframe_poses(i))
        if self.brightness_amplitude > 0:
            img *= np.float32(
                1.0 + self.brightness_amplitude * math.sin(2.0 * math.pi * self.timestamps[i] / self.brightness_period)
            )
        if self.noise_sigma > 0:
            rng = np.random.default_rng([self.noise_seed, i])
            img += np.float32(self.noise_sigma) * rng.standard_normal(img.shape, dtype=np.float32)
        return np.clip(np.rint(img), 0, 255).astype(np.uint8)

    def raycast(self, T_wc: np.ndarray, uv: np.ndarray):
        """True geometry at pixels uv (M, 2) seen from T_wc: world points (M, 3), camera depth z (M,), hit (M,).

        Misses (rays that hit no rectangle) have NaN points and depths.
        """
        T_wc = np.asarray(T_wc, dtype=np.float64)
        rays = self.camera.unproject_rays(np.asarray(uv, dtype=np.float64).reshape(-1, 2))
        d = rays @ T_wc[:3, :3].T
        t, k, _, _ = intersect_rays(T_wc[:3, 3], d, self._packed)
        hit = k >= 0
        t = np.where(hit, t, np.nan)
        return T_wc[:3, 3] + t[:, None] * d, t * rays[:, 2], hit


def load_scene(name_or_path: str | Path) -> Scene:
    """A bundled scene by name (``data/synthetic/<name>.yaml``) or a scene file; InputError if unusable."""
    name, spec, path = resolve_scene(name_or_path)
    return Scene(name, spec, path)
