"""The dominant plane's grid (PTAM Fig. 1; code ``ARDriver::DrawFadingGrid``), sampled densely and projected
through the full camera model so its lines bend with the lens distortion.

Lines along x come first (``2h + 1`` of them, at y = -h·s … h·s), then lines along y; each holds
``2h·k + 1`` samples (k per cell), so grid vertex (x_j, y_i) is sample ``j·k`` of line ``i``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera.camproj_kernels import project_points


@dataclass(frozen=True)
class Grid:
    half_cells: int
    spacing: float
    samples_per_cell: int
    lines: np.ndarray  # (2·(2h+1), 2h·k + 1, 3) plane-frame samples

    @property
    def n_lines_per_axis(self) -> int:
        return 2 * self.half_cells + 1

    @property
    def vertices(self) -> np.ndarray:
        """((2h+1)², 3) plane-frame vertices, row i = line along x at y_i, column j = x_j."""
        n, k = self.n_lines_per_axis, self.samples_per_cell
        return self.lines[:n, ::k].reshape(-1, 3)


def make_grid(half_cells: int, spacing: float, samples_per_cell: int) -> Grid:
    h, k = int(half_cells), int(samples_per_cell)
    ticks = spacing * np.arange(-h, h + 1, dtype=np.float64)
    along = spacing * np.linspace(-h, h, 2 * h * k + 1)
    n, s = len(ticks), len(along)
    lines = np.zeros((2 * n, s, 3))
    lines[:n, :, 0] = along[None, :]
    lines[:n, :, 1] = ticks[:, None]
    lines[n:, :, 0] = ticks[:, None]
    lines[n:, :, 1] = along[None, :]
    return Grid(h, float(spacing), k, lines)


@dataclass(frozen=True)
class ProjectedGrid:
    uv: np.ndarray  # (L, S, 2) pixel positions of the samples
    ok: np.ndarray  # (L, S) in front of the camera and within the projectable radius
    vertex_uv: np.ndarray  # ((2h+1)², 2), as Grid.vertices
    vertex_ok: np.ndarray  # ((2h+1)²,)


def project_grid(grid: Grid, cam_params: np.ndarray, T_cp: np.ndarray) -> ProjectedGrid:
    """Samples through plane→camera ``T_cp`` and the lens model (``CameraModel.kernel_params()``)."""
    L, S, _ = grid.lines.shape
    Xc = grid.lines.reshape(-1, 3) @ T_cp[:3, :3].T + T_cp[:3, 3]
    uv, ok = project_points(cam_params, np.ascontiguousarray(Xc))
    uv = uv.reshape(L, S, 2)
    ok = ok.reshape(L, S)
    n, k = grid.n_lines_per_axis, grid.samples_per_cell
    return ProjectedGrid(uv, ok, uv[:n, ::k].reshape(-1, 2), ok[:n, ::k].reshape(-1))
