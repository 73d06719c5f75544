"""The whole system on the synthetic two-wall sequence (PTAM §7.3): initialisation, tracking and mapping.

``two_wall_short`` (200 frames, 5.6 m of the path) is rendered once into the cache. Sync mode is
deterministic; async mode runs the mapper in its own thread.
"""

import numpy as np
import pytest

from ptam.camera import load_camera
from ptam.capture import open_dataset
from ptam.config import load_config
from ptam.eval import associate, ate, read_tum
from ptam.synthetic import ensure_sequence
from ptam.system import System


@pytest.fixture(scope="module")
def short():
    return ensure_sequence("two_wall_short")


def _run(d, mode):
    cfg = load_config()
    camera = load_camera(d / "camera.yaml")
    with open_dataset(d) as src, System(camera, cfg, mode=mode) as system:
        for frame in src:
            system.process(frame)
    return system


def _score(d, system):
    t_gt, T_gt = read_tum(d / "groundtruth.txt")
    t = np.array([p[0] for p in system.trajectory])
    T = np.array([p[1] for p in system.trajectory])
    ig, ie = associate(t_gt, t, 0.01)
    r = ate(T_gt[ig, :3, 3], T[ie, :3, 3])
    length = float(np.linalg.norm(np.diff(T_gt[:, :3, 3], axis=0), axis=1).sum())
    return len(ig) / len(t_gt), r.rmse, length


@pytest.fixture(scope="module")
def sync_runs(short):
    return _run(short, "sync"), _run(short, "sync")


def test_sync_initialises_tracks_and_maps_accurately(short, sync_runs):
    system = sync_runs[0]
    fraction, rmse, length = _score(short, system)
    snap = system.mapper.snapshot
    print(f"tracked {fraction:.3f}, ATE {1e3 * rmse:.2f} mm over {length:.2f} m, "
          f"{snap.n_keyframes} keyframes, {snap.n_points} points")
    assert system.stats.init_attempts >= 1 and system.mapper.initialised
    assert fraction >= 0.98
    assert rmse <= 0.001 * length
    assert snap.n_keyframes >= 4 and snap.n_points > 1000


def test_sync_runs_are_identical(sync_runs):
    a, b = sync_runs
    Ta = np.array([p[1] for p in a.trajectory])
    Tb = np.array([p[1] for p in b.trajectory])
    assert Ta.shape == Tb.shape and np.array_equal(Ta, Tb)


def test_async_tracks_with_the_mapper_in_its_own_thread(short):
    system = _run(short, "async")
    fraction, rmse, length = _score(short, system)
    print(f"async: tracked {fraction:.3f}, ATE {1e3 * rmse:.2f} mm")
    assert fraction >= 0.95
    assert rmse <= 0.002 * length
