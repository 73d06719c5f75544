import numpy as np
import pytest

from ptam.config import default_config
from ptam.errors import PtamError
from ptam.geometry import se3
from ptam.image.pyramid import Pyramid
from ptam.map.keyframe import KeyFrame
from ptam.map.map import Map

CFG = default_config().image


def _kf(m: Map, seed: int) -> KeyFrame:
    img = np.random.default_rng(seed).integers(0, 256, (96, 128)).astype(np.uint8)
    return KeyFrame(m.next_keyframe_id, Pyramid.build(img, CFG), 2.0, 0.5)


def _pose(i: int) -> np.ndarray:
    return se3.exp(np.array([0.1 * i, 0.0, 0.0, 0.0, 0.02 * i, 0.0]))


def _filled(n_kf=3, n_pts=10):
    m = Map()
    for i in range(n_kf):
        assert m.add_keyframe(_kf(m, i), _pose(i)) == i
    rng = np.random.default_rng(5)
    idx = m.add_points(
        rng.normal(size=(n_pts, 3)),
        np.tile([0.0, 0.0, -1.0], (n_pts, 1)),
        rng.integers(0, n_kf, n_pts),
        rng.integers(0, 4, n_pts),
        rng.uniform(0, 50, (n_pts, 2)),
    )
    assert np.array_equal(idx, np.arange(n_pts))
    m.add_measurements(
        np.repeat(np.arange(n_kf), n_pts), np.tile(np.arange(n_pts), n_kf), rng.uniform(0, 100, (n_kf * n_pts, 2)), 0
    )
    return m


def test_add_and_snapshot_contents():
    m = _filled()
    s = m.snapshot()
    assert s.n_keyframes == 3 and s.n_points == 10 and len(s.meas_kf) == 30
    assert s.version == m.version and m.snapshot() is s  # cached while unchanged
    assert np.allclose(s.kf_T_cw[2], _pose(2))
    assert np.allclose(s.camera_centres[2], se3.inv(_pose(2))[:3, 3])
    assert [st.shape for st in s.kf_images] == [(3, 96, 128), (3, 48, 64), (3, 24, 32), (3, 12, 16)]
    assert np.array_equal(s.kf_images[1][2], s.keyframes[2].pyramid.levels[1])
    assert s.X.dtype == np.float64 and s.source_kf.dtype == np.int32 and s.source_level.dtype == np.int8
    assert s.meas_kf.dtype == np.int32 and s.meas_pt.dtype == np.int32 and s.meas_level.dtype == np.int8
    assert np.array_equal(s.meas_level, np.zeros(30))


def test_snapshot_is_read_only_and_unchanged_by_later_edits():
    m = _filled()
    s = m.snapshot()
    arrays = [
        s.kf_T_cw,
        *s.kf_images,
        s.X,
        s.normal,
        s.source_kf,
        s.source_level,
        s.source_xy,
        s.bad,
        s.meas_kf,
        s.meas_pt,
        s.meas_xy,
        s.meas_level,
        s.good_point_indices,
    ]
    assert not any(a.flags.writeable for a in arrays)
    with pytest.raises(ValueError):
        s.X[0, 0] = 1.0
    before = [a.copy() for a in arrays]
    # enough keyframes, points and measurements to force every capacity to grow several times
    for i in range(3, 40):
        m.add_keyframe(_kf(m, i), _pose(i))
    m.add_points(np.ones((500, 3)), np.tile([0.0, 0.0, -1.0], (500, 1)), 0, 1, np.zeros((500, 2)))
    m.add_measurements(np.zeros(500, int), np.arange(10, 510), np.zeros((500, 2)), 1)
    m.set_poses([0, 1], np.stack([np.eye(4), np.eye(4)]))
    m.set_points([0, 3], np.zeros((2, 3)))
    m.mark_bad([1, 2])
    m.remove_measurements(m.meas_pt == 4)
    assert all(np.array_equal(a, b) for a, b in zip(arrays, before))
    assert s.n_keyframes == 3 and s.n_points == 10
    s2 = m.snapshot()
    assert s2.version > s.version and s2.n_keyframes == 40 and s2.n_points == 508 and len(s2.X) == 510
    assert np.array_equal(s2.kf_images[0][:3], s.kf_images[0]) and np.array_equal(s2.kf_T_cw[0], np.eye(4))
    assert np.array_equal(s2.X[[0, 3]], np.zeros((2, 3)))
    assert s2.bad[[1, 2]].all() and not np.isin([1, 2, 4], s2.meas_pt).any()
    assert len(s2.meas_pt) == 30 - 3 * 3 + 500
    assert np.array_equal(s2.good_point_indices, np.setdiff1d(np.arange(510), [1, 2]))
    # the live views are read-only too: mutation goes through the methods, which bump the version
    with pytest.raises(ValueError):
        m.X[0, 0] = 1.0


def test_bad_calls_raise_ptam_errors():
    m = _filled()
    with pytest.raises(PtamError):
        m.add_keyframe(KeyFrame(7, m.keyframes[0].pyramid, 1.0, 0.1), np.eye(4))
    with pytest.raises(PtamError):
        m.add_points(np.zeros((2, 3)), np.zeros((2, 3)), [0, 9], 0, np.zeros((2, 2)))
    with pytest.raises(PtamError):
        m.add_measurements([0], [10], np.zeros((1, 2)), 0)
    with pytest.raises(PtamError):
        m.remove_measurements(np.zeros(3, bool))
    with pytest.raises(PtamError):
        m.set_poses([5], np.eye(4)[None])
    with pytest.raises(PtamError):
        KeyFrame.depth_stats([])
    assert np.allclose(KeyFrame.depth_stats([1.0, 3.0]), (2.0, 1.0))
