"""Synthetic calibration sequences: a chessboard seen from varied poses through a known camera.

The board lies in its own z = 0 plane; inner corner (i, j) sits at (i·s, j·s, 0) for square size s, the
checker area spans one square beyond the inner corners on every side and a white margin surrounds it (the
quiet zone chessboard detectors need). Each view is ray-cast through the camera model (distortion
included) and box-filtered over the pixel's area: rays through the pixel corners are intersected with the
board once, pixels whose four corners fall in one region take its shade, and only pixels on an edge are
supersampled, with board coordinates interpolated bilinearly between the pixel's corners (the pixel→board
map is smooth, so this is exact to far below the 0.05 px the corner accuracy needs). The samples form a
Fibonacci lattice rather than an n×n grid: every sample has its own column and row, so an edge parallel to
the pixel grid is located to 1/N px with N samples instead of 1/√N.

Board poses cover the image, its corners included, with tilts up to a maximum angle from facing the
camera and in-plane rolls, at distances where the board fills a chosen fraction of the image width.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml

from ..camera import CameraModel, FovCamera, RadTanCamera, camera_from_dict, save_camera
from ..camera.chessboard import Board
from ..config import Config, SynthCalibrationConfig, apply_overrides
from ..errors import ConfigError, InputError
from ..eval.tum_io import write_tum
from ..geometry import se3, so3
from ..vocabulary import DistortionModel
from .sequence import VIDEO_FILE, frame_name, write_video

CALIBRATION_SCENE = "calibration"  # the name `ptam synth` knows this generator by
SECTION = "synth_calibration"
_REGION_BACKGROUND = 0  # rays that miss the board (or hit it from behind the camera)
_REGION_MARGIN = 1  # the white paper around the checker area
_REGION_FIRST_SQUARE = 2
_EDGE_SAMPLES = 16  # points per board edge checked to lie inside the image (edges bow under distortion)
_MAX_PLACEMENT_TRIES = 200  # random draws per view before the scene is declared impossible


@dataclass(frozen=True)
class PrintedBoard:
    """A chessboard printed with ``margin`` squares of white paper round its checker area."""

    board: Board
    margin: float

    @property
    def cols(self) -> int:
        return self.board.cols

    @property
    def rows(self) -> int:
        return self.board.rows

    @property
    def square(self) -> float:
        return self.board.square

    def extent(self) -> tuple[float, float, float, float]:
        """(x0, x1, y0, y1) of the paper, margin included."""
        pad = (1.0 + self.margin) * self.square
        return -pad, self.cols * self.square - self.square + pad, -pad, self.rows * self.square - self.square + pad

    def outline(self) -> np.ndarray:
        """Points along the paper's edge (4·_EDGE_SAMPLES, 3)."""
        x0, x1, y0, y1 = self.extent()
        t = np.linspace(0.0, 1.0, _EDGE_SAMPLES, endpoint=False)
        xs, ys = x0 + (x1 - x0) * t, y0 + (y1 - y0) * t
        edges = [
            np.stack([xs, np.full_like(t, y0)], 1),
            np.stack([np.full_like(t, x1), ys], 1),
            np.stack([xs[::-1] + (x1 - x0) / _EDGE_SAMPLES, np.full_like(t, y1)], 1),
            np.stack([np.full_like(t, x0), ys[::-1] + (y1 - y0) / _EDGE_SAMPLES], 1),
        ]
        xy = np.concatenate(edges)
        return np.concatenate([xy, np.zeros((len(xy), 1))], axis=1)

    def regions(self, xy: np.ndarray, hit: np.ndarray) -> np.ndarray:
        """Region id of board points (..., 2): background, margin, or one id per checker square."""
        s = self.square
        x0, x1, y0, y1 = self.extent()
        ix = np.floor(xy[..., 0] / s).astype(np.int64) + 1
        iy = np.floor(xy[..., 1] / s).astype(np.int64) + 1
        on_paper = hit & (xy[..., 0] >= x0) & (xy[..., 0] < x1) & (xy[..., 1] >= y0) & (xy[..., 1] < y1)
        checker = on_paper & (ix >= 0) & (ix <= self.cols) & (iy >= 0) & (iy <= self.rows)
        square_id = _REGION_FIRST_SQUARE + iy * (self.cols + 1) + ix
        return np.where(checker, square_id, np.where(on_paper, _REGION_MARGIN, _REGION_BACKGROUND))

    def shade_table(self, black: float, white: float, background: float) -> np.ndarray:
        """Grey level per region id; the square touching the first inner corner's top-left is black."""
        n = (self.cols + 1) * (self.rows + 1)
        ix, iy = np.arange(n) % (self.cols + 1), np.arange(n) // (self.cols + 1)
        squares = np.where((ix + iy) % 2 == 0, black, white)
        return np.concatenate([[background, white], squares]).astype(np.float64)


def lattice_samples(n: int) -> np.ndarray:
    """(n, 2) sample positions in the unit pixel [0, 1]²: the rank-1 lattice with generator round(n/φ),
    which for a Fibonacci number n is the Fibonacci lattice, among the most uniform point sets in 2-D."""
    g = round(n * (math.sqrt(5.0) - 1.0) / 2.0)
    k = np.arange(n)
    return np.stack([(k + 0.5) / n, np.mod(k * g + 0.5, n) / n], axis=1)


class BoardRenderer:
    """Renders ``board`` seen through ``camera``; the pixel-corner rays are computed once per camera."""

    def __init__(self, camera: CameraModel, board: PrintedBoard, samples: int, shades: tuple[float, float, float]):
        self.camera = camera
        self.board = board
        self.shades = board.shade_table(*shades)
        W, H = camera.width, camera.height
        u, v = np.meshgrid(np.arange(W + 1) - 0.5, np.arange(H + 1) - 0.5, indexing="xy")
        xy = camera.unproject(np.stack([u, v], axis=-1).reshape(-1, 2))
        self.rays = np.concatenate([xy, np.ones((len(xy), 1))], axis=1).reshape(H + 1, W + 1, 3)
        self.sub = lattice_samples(samples)

    def board_coords(self, T_cb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Board-plane (x, y) (H+1, W+1, 2) where each pixel-corner ray meets the board, and whether it does."""
        R, t = T_cb[:3, :3], T_cb[:3, 3]
        n = R[:, 2]
        denom = self.rays @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = (n @ t) / denom
        hit = np.isfinite(lam) & (lam > 0)
        X = np.where(hit[..., None], self.rays * lam[..., None], 0.0)
        return (X - t) @ R[:, :2], hit

    def render(self, T_cb: np.ndarray) -> np.ndarray:
        """Box-filtered grey image (H, W) float64 of the board at pose ``T_cb`` (board → camera)."""
        xy, hit = self.board_coords(np.asarray(T_cb, dtype=np.float64))
        reg = self.board.regions(xy, hit)
        c00, c01, c10, c11 = reg[:-1, :-1], reg[:-1, 1:], reg[1:, :-1], reg[1:, 1:]
        img = self.shades[c00].copy()
        edge = (c00 != c01) | (c00 != c10) | (c00 != c11)
        ys, xs = np.nonzero(edge)
        if len(ys) == 0:
            return img
        all_hit = hit[ys, xs] & hit[ys, xs + 1] & hit[ys + 1, xs] & hit[ys + 1, xs + 1]
        a, b = self.sub[:, 0][None, :, None], self.sub[:, 1][None, :, None]
        p00, p01 = xy[ys, xs][:, None], xy[ys, xs + 1][:, None]
        p10, p11 = xy[ys + 1, xs][:, None], xy[ys + 1, xs + 1][:, None]
        samples = (1 - b) * ((1 - a) * p00 + a * p01) + b * ((1 - a) * p10 + a * p11)  # (E, n, 2)
        sreg = self.board.regions(samples, np.broadcast_to(all_hit[:, None], samples.shape[:2]))
        img[ys, xs] = self.shades[sreg].mean(axis=1)
        return img


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation taking unit vector a to unit vector b."""
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(a @ b)
    if s < 1e-12:
        return np.eye(3)
    return so3.exp(axis / s * math.atan2(s, c))


def board_fits(camera: CameraModel, board: PrintedBoard, T_cb: np.ndarray, border_px: float) -> bool:
    """The whole paper lies in front of the camera and inside the image, ``border_px`` from its edge."""
    X = board.outline() @ T_cb[:3, :3].T + T_cb[:3, 3]
    if not np.all(camera.valid(X, 1.0)):
        return False
    return bool(np.all(camera.in_image(camera.project(X), border_px)))


def board_poses(camera: CameraModel, board: PrintedBoard, cfg: SynthCalibrationConfig) -> np.ndarray:
    """``cfg.views`` poses T_cb (N, 4, 4) spreading the board over the image, its corners and its tilts.

    View k aims the board centre at a cell of a stratified grid over the image (shuffled), so the views
    together reach every part of it; a draw that does not fit is pulled towards the image centre and
    redrawn.
    """
    rng = np.random.default_rng(cfg.seed)
    W, H = camera.width, camera.height
    g = max(2, math.ceil(math.sqrt(cfg.views)))
    cells = np.stack(np.meshgrid(np.arange(g), np.arange(g), indexing="xy"), -1).reshape(-1, 2)
    cells = np.concatenate([cells] * math.ceil(cfg.views / len(cells)))[: cfg.views]
    cells = cells[rng.permutation(len(cells))]
    x0, x1, y0, y1 = board.extent()
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
    width_m = x1 - x0
    poses = []
    for cell in cells:
        target = (cell + rng.uniform(0.0, 1.0, 2)) / g  # in [0, 1]², reaching the image's edges
        for attempt in range(_MAX_PLACEMENT_TRIES):
            pull = attempt / _MAX_PLACEMENT_TRIES
            uv = np.array([W - 1.0, H - 1.0]) * (0.5 + (target - 0.5) * (1.0 - pull))
            tilt = math.radians(rng.uniform(0.0, cfg.tilt_max_deg))
            phi = rng.uniform(0.0, 2.0 * math.pi)
            roll = math.radians(rng.uniform(-cfg.roll_max_deg, cfg.roll_max_deg))
            ray = np.append(camera.unproject(uv[None])[0], 1.0)
            # Tilt is measured from facing the camera along the ray, so boards near the edges of a wide lens
            # are never seen edge-on.
            R_face = _rotation_between(np.array([0.0, 0.0, 1.0]), ray / np.linalg.norm(ray))
            R_tilt = so3.exp(np.array([math.cos(phi), math.sin(phi), 0.0]) * tilt)
            R = R_face @ R_tilt @ so3.exp(np.array([0.0, 0.0, roll]))
            fill = rng.uniform(*cfg.fill)
            depth = camera.fx * width_m / (fill * W)
            T = se3.from_Rt(R, ray * depth - R @ centre)
            if board_fits(camera, board, T, cfg.border_px):
                poses.append(T)
                break
        else:
            raise InputError(
                f"synthetic calibration: cannot place a {board.cols}x{board.rows} board in a "
                f"{W}x{H} image (lower 'fill' or 'tilt_max_deg')"
            )
    return np.stack(poses)


def true_corners(camera: CameraModel, board: Board, T_cb: np.ndarray) -> np.ndarray:
    """Exact pixel positions (N, cols·rows, 2) of the inner corners in every view."""
    X = board.points()
    Xc = np.einsum("nij,kj->nki", T_cb[:, :3, :3], X) + T_cb[:, None, :3, 3]
    return camera.project(Xc)


def default_camera(cfg: SynthCalibrationConfig) -> CameraModel:
    """The config's camera: fx = fy = focal_rel·W, principal point at the image centre."""
    W, H = cfg.size
    f = cfg.focal_rel * W
    cx, cy = (W - 1) / 2.0, (H - 1) / 2.0
    if cfg.model == DistortionModel.FOV:
        return FovCamera(W, H, f, f, cx, cy, cfg.omega)
    return RadTanCamera(W, H, f, f, cx, cy, *cfg.radtan)


@dataclass
class CalibrationSequence:
    camera: CameraModel
    board: PrintedBoard
    poses_T_cb: np.ndarray
    images: list[np.ndarray]

    def corners(self) -> np.ndarray:
        return true_corners(self.camera, self.board.board, self.poses_T_cb)


def render_calibration(cfg: SynthCalibrationConfig, camera: CameraModel | None = None) -> CalibrationSequence:
    """Render the calibration views of ``cfg`` (uint8 images) through ``camera`` (default from ``cfg``)."""
    camera = camera or default_camera(cfg)
    board = PrintedBoard(Board(cfg.board[0], cfg.board[1], cfg.square_m), cfg.margin_squares)
    poses = board_poses(camera, board, cfg)
    renderer = BoardRenderer(camera, board, cfg.edge_samples, (cfg.black, cfg.white, cfg.background))
    rng = np.random.default_rng([cfg.seed, 1])
    images = []
    for T in poses:
        img = renderer.render(T)
        if cfg.blur_sigma_px > 0:
            img = cv2.GaussianBlur(img, (0, 0), cfg.blur_sigma_px)
        if cfg.noise_sigma > 0:
            img = img + cfg.noise_sigma * rng.standard_normal(img.shape)
        images.append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
    return CalibrationSequence(camera, board, poses, images)


def is_calibration_scene(name_or_path: str) -> bool:
    """``calibration`` (the config's default board and camera) or a YAML file with a ``calibration:`` mapping."""
    if name_or_path == CALIBRATION_SCENE:
        return True
    if not (os.path.isfile(name_or_path) and name_or_path.endswith((".yaml", ".yml"))):
        return False
    try:
        with open(name_or_path) as f:
            d = yaml.safe_load(f)
    except (OSError, yaml.YAMLError, UnicodeDecodeError):
        return False
    return isinstance(d, dict) and "calibration" in d


def load_calibration_scene(name_or_path: str, cfg: Config) -> tuple[SynthCalibrationConfig, CameraModel]:
    """The ``synth_calibration`` config section and camera of a calibration scene.

    ``calibration`` is the section as configured (``--config`` / ``--set synth_calibration.KEY=VALUE``); a
    scene file overrides keys of the section under ``calibration:`` and may give the full camera under
    ``camera:`` (camera.yaml layout), which replaces the section's model, size, focal_rel, omega and radtan.
    """
    if name_or_path == CALIBRATION_SCENE:
        return cfg.synth_calibration, default_camera(cfg.synth_calibration)
    where = f"scene {name_or_path}"
    try:
        with open(name_or_path) as f:
            d = yaml.safe_load(f)
    except (OSError, yaml.YAMLError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read {where}: {str(e).splitlines()[0]}") from None
    if not isinstance(d, dict) or not isinstance(d.get("calibration", {}), dict):
        raise InputError(f"{where}: 'calibration' must be a mapping of synth_calibration keys")
    unknown = set(d) - {"calibration", "camera", "description"}
    if unknown:
        raise InputError(f"{where}: unknown key(s) {', '.join(sorted(map(str, unknown)))}")
    overrides = [f"{SECTION}.{k}={json.dumps(v)}" for k, v in d.get("calibration", {}).items()]
    try:
        section = apply_overrides(cfg, overrides).synth_calibration
    except ConfigError as e:
        raise InputError(f"{where}: {e}") from None
    camera = camera_from_dict(d["camera"], f"{where}.camera") if "camera" in d else default_camera(section)
    return section, camera


def write_calibration_sequence(
    seq: CalibrationSequence, section: SynthCalibrationConfig, out_dir: str, video: bool = False
) -> None:
    """TUM layout: ``rgb/NNNNNN.png``, ``rgb.txt``, ``camera.yaml`` (the true camera), ``groundtruth.txt``
    (camera poses in the board frame), ``corners.txt`` (true corner pixels, one view per line),
    ``scene.yaml`` (renders the same sequence again) and, with ``video``, ``video.avi``."""
    rgb = os.path.join(out_dir, "rgb")
    try:
        os.makedirs(rgb, exist_ok=True)
    except OSError as e:
        raise InputError(f"cannot create {rgb}: {e.strerror}") from None
    stamps = np.arange(len(seq.images)) / section.fps
    names = [frame_name(i) for i in range(len(seq.images))]
    for name, img in zip(names, seq.images):
        if not cv2.imwrite(os.path.join(out_dir, name), img):
            raise InputError(f"cannot write {os.path.join(out_dir, name)}")
    with open(os.path.join(out_dir, "rgb.txt"), "w") as f:
        f.write("# timestamp filename\n")
        f.writelines(f"{t:.6f} {name}\n" for t, name in zip(stamps, names))
    write_tum(
        os.path.join(out_dir, "groundtruth.txt"),
        stamps,
        se3.inv(seq.poses_T_cb),
        header="world = the board frame (x along its rows, y down its columns, z through it)",
    )
    np.savetxt(
        os.path.join(out_dir, "corners.txt"),
        seq.corners().reshape(len(seq.images), -1),
        fmt="%.6f",
        header=f"true inner-corner pixels u0 v0 u1 v1 ... of a {seq.board.cols}x{seq.board.rows} board",
    )
    save_camera(seq.camera, os.path.join(out_dir, "camera.yaml"))
    with open(os.path.join(out_dir, "scene.yaml"), "w") as f:
        yaml.safe_dump({"calibration": dataclasses.asdict(section), "camera": seq.camera.to_dict()}, f, sort_keys=False)
    if video:
        write_video(Path(out_dir) / VIDEO_FILE, seq.images, section.fps, seq.camera.size)


def synth_calibration(scene: str, out_dir: str, cfg: Config, video: bool = False) -> str:
    """``ptam synth calibration OUT``: render and write a calibration sequence; returns a one-line summary."""
    section, camera = load_calibration_scene(scene, cfg)
    seq = render_calibration(section, camera)
    write_calibration_sequence(seq, section, out_dir, video)
    b = seq.board
    return (
        f"wrote {out_dir}: {len(seq.images)} views of a {b.cols}x{b.rows} board ({b.square * 1000:g} mm squares) "
        f"through a {camera.model} camera {camera.width}x{camera.height} (true calibration in camera.yaml)"
    )
