"""Chessboard corners for calibration: the board, OpenCV's detector, and the choice of well-spread views.

Detection is OpenCV's (``findChessboardCornersSB`` or the classic ``findChessboardCorners``) behind its
cheap ``checkChessboard`` test, refined by ``cornerSubPix`` with a window scaled to the board's corner spacing
in the image (on rendered boards this halves the SB detector's own error, to ~0.04 px RMS). A video holds hundreds
of nearly identical frames, so a detection is kept only when the board has moved noticeably since every
kept one (a 4-corner descriptor), and the fit uses a subset chosen to cover the image (greedy set cover of
a grid of cells) and then the poses (farthest-point sampling of the descriptor).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import cv2
import numpy as np

from ..config import CalibrateConfig
from ..errors import InputError

_BOARD = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
_MIN_SUBPIX_HALF_WINDOW = 2


@dataclass(frozen=True)
class Board:
    """``cols`` × ``rows`` inner corners, ``square`` metres apart."""

    cols: int
    rows: int
    square: float

    @property
    def pattern_size(self) -> tuple[int, int]:
        return self.cols, self.rows

    def points(self) -> np.ndarray:
        """Inner corners (cols·rows, 3) in the board's z = 0 plane, row by row (OpenCV's order)."""
        i, j = np.meshgrid(np.arange(self.cols), np.arange(self.rows), indexing="xy")
        return np.stack([i.ravel() * self.square, j.ravel() * self.square, np.zeros(i.size)], axis=1)

    def outer_indices(self) -> np.ndarray:
        """The four outermost inner corners, going round the board."""
        c, r = self.cols, self.rows
        return np.array([0, c - 1, r * c - 1, (r - 1) * c])


def parse_board(text: str, square: float) -> Board:
    """``"9x6"`` and a square size in metres -> Board; InputError on anything else."""
    m = _BOARD.match(str(text))
    if not m:
        raise InputError(f"--board must be COLSxROWS inner corners, e.g. 9x6, got '{text}'")
    cols, rows = int(m.group(1)), int(m.group(2))
    if cols < 3 or rows < 3:
        raise InputError(f"--board needs at least 3x3 inner corners, got {cols}x{rows}")
    if cols == rows:
        # A square board's corner order is ambiguous up to a 90° turn, which no pose can absorb.
        raise InputError(f"--board {cols}x{rows}: use a board with different numbers of inner corners per side")
    if not (square > 0 and np.isfinite(square)):
        raise InputError(f"--square must be a positive size in metres, got {square}")
    return Board(cols, rows, float(square))


def _subpix_half_window(corners: np.ndarray, board: Board, cfg: CalibrateConfig) -> int:
    grid = corners.reshape(board.rows, board.cols, 2)
    spacing = min(
        np.linalg.norm(np.diff(grid, axis=0), axis=-1).min(), np.linalg.norm(np.diff(grid, axis=1), axis=-1).min()
    )
    return int(np.clip(cfg.subpix_window_frac * spacing, _MIN_SUBPIX_HALF_WINDOW, cfg.subpix_window_max_px))


def detect_corners(grey: np.ndarray, board: Board, cfg: CalibrateConfig) -> np.ndarray | None:
    """Sub-pixel inner corners (cols·rows, 2) of the whole board in a grey uint8 image, or None."""
    if cfg.fast_check and not cv2.checkChessboard(grey, board.pattern_size):
        return None
    if cfg.detector == "sb":
        found, corners = cv2.findChessboardCornersSB(grey, board.pattern_size, flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
    else:
        flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
        found, corners = cv2.findChessboardCorners(grey, board.pattern_size, flags=flags)
    if not found or corners is None or len(corners) != board.cols * board.rows:
        return None
    corners = corners.reshape(-1, 1, 2).astype(np.float32)
    w = _subpix_half_window(corners.reshape(-1, 2), board, cfg)
    corners = cv2.cornerSubPix(grey, corners, (w, w), (-1, -1), _SUBPIX_CRITERIA)
    return corners.reshape(-1, 2).astype(np.float64)


@dataclass(frozen=True)
class View:
    """One detected board: the frame it came from and its corners (cols·rows, 2) in pixels."""

    frame: int
    timestamp: float
    corners: np.ndarray


def descriptor_distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """RMS displacement of the four outer corners, (..., 4, 2) pairs broadcast, allowing the 180° re-ordering
    a detector may return for the same pose."""
    d = np.sqrt(np.mean(np.sum((a - b) ** 2, axis=-1), axis=-1))
    d_flip = np.sqrt(np.mean(np.sum((a - b[..., ::-1, :]) ** 2, axis=-1), axis=-1))
    return np.minimum(d, d_flip)


class ViewCollector:
    """Detects the board in frames and keeps the detections that differ from every kept one."""

    def __init__(self, board: Board, size: tuple[int, int], cfg: CalibrateConfig):
        self.board = board
        self.size = size
        self.cfg = cfg
        self.views: list[View] = []
        self.detections = 0
        self._outer = board.outer_indices()
        self._min_change_px = cfg.min_view_change * float(np.hypot(*size))

    @property
    def full(self) -> bool:
        return len(self.views) >= self.cfg.max_candidates

    def add(self, frame: int, timestamp: float, grey: np.ndarray) -> bool:
        """Detect the board in ``grey``; True if the view was kept."""
        if grey.shape[::-1] != tuple(self.size):
            w, h = self.size
            raise InputError(f"frame {frame} is {grey.shape[1]}x{grey.shape[0]}, expected {w}x{h}")
        if self.full:
            return False
        corners = detect_corners(grey, self.board, self.cfg)
        if corners is None:
            return False
        self.detections += 1
        if self.views:
            kept = np.stack([v.corners[self._outer] for v in self.views])
            if descriptor_distance(kept, corners[self._outer]).min() < self._min_change_px:
                return False
        self.views.append(View(frame, timestamp, corners))
        return True


def cell_counts(corners: np.ndarray, size: tuple[int, int], grid: int) -> np.ndarray:
    """Corners per cell of a grid × grid partition of the image: (…, N, 2) points -> (grid, grid) counts."""
    pts = corners.reshape(-1, 2)
    col = np.clip((pts[:, 0] / size[0] * grid).astype(int), 0, grid - 1)
    row = np.clip((pts[:, 1] / size[1] * grid).astype(int), 0, grid - 1)
    counts = np.zeros((grid, grid), dtype=np.int64)
    np.add.at(counts, (row, col), 1)
    return counts


def select_views(views: list[View], board: Board, size: tuple[int, int], cfg: CalibrateConfig) -> list[View]:
    """Up to ``cfg.max_views`` views: first a greedy cover of the image's grid cells, then the views
    farthest (in outer-corner displacement) from those already chosen, which spreads position, scale,
    tilt and roll."""
    if len(views) <= cfg.max_views:
        return list(views)
    g = cfg.selection_grid
    cells = np.stack([cell_counts(v.corners, size, g).ravel() > 0 for v in views])  # (M, g²)
    chosen: list[int] = []
    covered = np.zeros(g * g, dtype=bool)
    while len(chosen) < cfg.max_views:
        gain = (cells & ~covered).sum(axis=1)
        gain[chosen] = -1
        best = int(np.argmax(gain))
        if gain[best] <= 0:
            break
        chosen.append(best)
        covered |= cells[best]
    outer = np.stack([v.corners[board.outer_indices()] for v in views])  # (M, 4, 2)
    nearest = np.full(len(views), np.inf)
    for i in chosen:
        nearest = np.minimum(nearest, descriptor_distance(outer, outer[i]))
    if not chosen:
        chosen.append(int(np.argmax(np.ptp(outer.reshape(len(views), -1), axis=1))))
        nearest = descriptor_distance(outer, outer[chosen[0]])
    while len(chosen) < cfg.max_views:
        nearest[chosen] = -1.0
        best = int(np.argmax(nearest))
        chosen.append(best)
        nearest = np.minimum(nearest, descriptor_distance(outer, outer[best]))
    return [views[i] for i in sorted(chosen)]


_CELL_NAMES_3 = [
    ["top-left", "top", "top-right"],
    ["left", "centre", "right"],
    ["bottom-left", "bottom", "bottom-right"],
]


def missing_cells(corners: np.ndarray, size: tuple[int, int], grid: int) -> list[str]:
    """Names of the grid cells of the image that no detected corner touches."""
    counts = cell_counts(corners, size, grid)
    rows, cols = np.nonzero(counts == 0)
    if grid == 3:
        return [_CELL_NAMES_3[r][c] for r, c in zip(rows, cols)]
    return [f"row {r + 1} col {c + 1}" for r, c in zip(rows, cols)]
