"""The synthetic calibration renderer: exact box-filtered pixels, true corners, poses that cover the image."""

import numpy as np

from ptam.camera import FovCamera, RadTanCamera
from ptam.camera.chessboard import Board, cell_counts
from ptam.config import default_config
from ptam.synthetic.board_sequence import BoardRenderer, PrintedBoard, board_fits, board_poses, true_corners

CFG = default_config().synth_calibration
BOARD = PrintedBoard(Board(9, 6, 0.04), 1.0)
SHADES = (30.0, 220.0, 110.0)


def board_xy(camera, T_cb, uv):
    """Exact board-plane coordinates of pixels (M, 2): unproject, intersect the board."""
    xy = camera.unproject(np.asarray(uv, dtype=float).reshape(-1, 2))
    rays = np.concatenate([xy, np.ones((len(xy), 1))], axis=1)
    R, t = T_cb[:3, :3], T_cb[:3, 3]
    lam = (R[:, 2] @ t) / (rays @ R[:, 2])
    return (rays * lam[:, None] - t) @ R[:, :2]


def reference_render(camera, board, T_cb, offsets, u0, v0, size):
    """Brute force: every sample of every pixel unprojected exactly through the camera."""
    u, v = np.meshgrid(np.arange(u0, u0 + size), np.arange(v0, v0 + size), indexing="xy")
    uv = np.stack([u[..., None] - 0.5 + offsets[:, 0], v[..., None] - 0.5 + offsets[:, 1]], axis=-1)
    pts = board_xy(camera, T_cb, uv).reshape(uv.shape)
    shades = board.shade_table(*SHADES)
    return shades[board.regions(pts, np.ones(pts.shape[:-1], bool))].mean(axis=-1)


CAMERAS = (
    FovCamera(640, 480, 384.0, 384.0, 319.5, 239.5, 0.9),
    RadTanCamera(640, 480, 512.0, 512.0, 319.5, 239.5, -0.25, 0.08, 0.001, -0.0005, 0.0),
)


def test_renderer_matches_exact_per_sample_unprojection():
    """Only edge pixels are supersampled, with board coordinates interpolated inside the pixel: the result
    equals per-sample exact ray casting to within one sample's weight."""
    cfg = default_config().replace(**{"synth_calibration.views": 3}).synth_calibration
    for camera in CAMERAS:
        r = BoardRenderer(camera, BOARD, cfg.edge_samples, SHADES)
        for T in board_poses(camera, BOARD, cfg):
            img = r.render(T)
            c = true_corners(camera, BOARD.board, T[None])[0][20]  # an inner corner: four squares meet
            u0, v0 = int(c[0]) - 10, int(c[1]) - 10
            ref = reference_render(camera, BOARD, T, r.sub, u0, v0, 21)
            diff = np.abs(img[v0 : v0 + 21, u0 : u0 + 21] - ref)
            assert diff.max() <= (SHADES[1] - SHADES[0]) / cfg.edge_samples + 1e-9
            assert diff.mean() < 0.05  # grey levels
            assert img.min() == SHADES[0] and img.max() == SHADES[1]


def edge_crossing(camera, T, x_board, v, u):
    """The u where image row v crosses the board line x = x_board (secant iterations on exact unprojection)."""
    f = lambda uu: board_xy(camera, T, [[uu, v]])[0, 0] - x_board  # noqa: E731
    u1 = u + 1.0
    for _ in range(30):
        f0, f1 = f(u), f(u1)
        if f1 == f0:
            break
        u, u1 = u1, u1 - f1 * (u1 - u) / (f1 - f0)
    return u1


def test_rendered_edges_sit_where_the_camera_model_puts_them():
    """Box filtering preserves area: along an image row the coverage of a square summed over the pixels
    across one of its vertical edges gives that edge's sub-pixel position, which must match the exact
    crossing of the row with the board line. This is what makes rendered corners accurate (< 0.05 px)."""
    cfg = default_config().replace(**{"synth_calibration.views": 4}).synth_calibration
    half = 6
    errors = []
    for camera in CAMERAS:
        r = BoardRenderer(camera, BOARD, cfg.edge_samples, SHADES)
        for T in board_poses(camera, BOARD, cfg):
            img = r.render(T)
            for i in range(BOARD.cols):
                for j in range(-1, BOARD.rows):
                    X = np.array([[i * BOARD.square, (j + 0.5) * BOARD.square, 0.0]])
                    u_p, v_p = camera.project(X @ T[:3, :3].T + T[:3, 3])[0]
                    v = int(round(v_p))
                    u_e = edge_crossing(camera, T, i * BOARD.square, v, u_p)
                    a = int(round(u_e)) - half
                    f = (img[v, a : a + 2 * half + 1] - SHADES[0]) / (SHADES[1] - SHADES[0])
                    if {f[0], f[-1]} != {0.0, 1.0}:
                        continue  # the row leaves the two squares (a corner or another edge is near)
                    covered = f.sum() if f[0] == 1.0 else (1.0 - f).sum()
                    errors.append(a - 0.5 + covered - u_e)
    errors = np.abs(errors)
    assert len(errors) > 200
    assert errors.max() < 0.05 and errors.mean() < 0.01


def test_poses_cover_the_image_and_fit_inside_it():
    camera = FovCamera(640, 480, 384.0, 384.0, 319.5, 239.5, 0.9)
    poses = board_poses(camera, BOARD, CFG)
    assert len(poses) == CFG.views
    assert all(board_fits(camera, BOARD, T, CFG.border_px) for T in poses)
    corners = true_corners(camera, BOARD.board, poses)
    assert np.all(cell_counts(corners, camera.size, 3) > 0)  # every ninth of the image, corners included
    normal_to_ray = []
    for T in poses:
        centre = T[:3, :3] @ np.array([0.16, 0.1, 0.0]) + T[:3, 3]
        normal_to_ray.append(np.degrees(np.arccos(abs(T[:3, 2] @ centre) / np.linalg.norm(centre))))
    assert max(normal_to_ray) > 35.0 and max(normal_to_ray) <= CFG.tilt_max_deg + 1.0
