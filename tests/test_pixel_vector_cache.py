"""The tracker's cache of patch pixel vectors (PTAM code ``RefreshPixelVectors``) equals recomputing every point
of each new snapshot, while a local change recomputes only the points it touched."""

from types import SimpleNamespace

import numpy as np
import pytest

from ptam.geometry import se3
from ptam.patch.warp import PixelVectorCache, patch_pixel_vectors
from tests.support.cameras import CAMERAS

N_KF, N_PT = 6, 3000


def _snapshot(rng):
    kf_T_cw = np.stack([se3.exp(np.concatenate([rng.normal(0, 0.1, 3), rng.normal(0, 0.05, 3)])) for _ in range(N_KF)])
    source_kf = rng.integers(0, N_KF, N_PT).astype(np.int32)
    Xc = np.concatenate([rng.uniform(-1, 1, (N_PT, 2)), rng.uniform(1, 4, (N_PT, 1))], axis=1)
    X = np.einsum("nji,nj->ni", kf_T_cw[source_kf, :3, :3], Xc - kf_T_cw[source_kf, :3, 3])
    normal = rng.normal(size=(N_PT, 3))
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    return SimpleNamespace(
        kf_T_cw=kf_T_cw,
        X=X,
        normal=normal,
        source_kf=source_kf,
        source_level=rng.integers(0, 4, N_PT).astype(np.int8),
        source_xy=rng.uniform(20, 60, (N_PT, 2)),
    )


def _changed(s, **arrays):
    return SimpleNamespace(**{**vars(s), **arrays})


def _full(cam, s):
    return patch_pixel_vectors(cam, s.kf_T_cw, s.X, s.normal, s.source_kf, s.source_level, s.source_xy)


@pytest.mark.parametrize("name", list(CAMERAS))
def test_cache_equals_full_recomputation(name, monkeypatch):
    cam = CAMERAS[name]
    rng = np.random.default_rng(3)
    s0 = _snapshot(rng)
    moved = s0.X.copy()
    moved[100:400] += rng.normal(0, 0.01, (300, 3))  # a local BA
    poses = s0.kf_T_cw.copy()
    poses[2] = se3.exp(rng.normal(0, 0.01, 6)) @ poses[2]  # one keyframe adjusted
    grown = _snapshot(np.random.default_rng(4))  # more points appended to s2's
    s1 = _changed(s0, X=moved)
    s2 = _changed(s1, kf_T_cw=poses)
    s3 = _changed(
        s2,
        **{k: np.concatenate([getattr(s2, k), getattr(grown, k)[:500]]) for k in vars(s2) if k != "kf_T_cw"},
    )
    calls = []
    import ptam.patch.warp as warp

    real = warp.patch_pixel_vectors
    monkeypatch.setattr(warp, "patch_pixel_vectors", lambda cam, T, X, *a: calls.append(len(X)) or real(cam, T, X, *a))
    cache = PixelVectorCache(cam)
    for s in (s0, s1, s1, s2, s3):
        right, down = cache.vectors(s)
        full_right, full_down = _full(cam, s)
        assert np.array_equal(right, full_right) and np.array_equal(down, full_down)
    points_of_kf2 = int((s0.source_kf == 2).sum())
    # s0 all; s1 the 300 moved; s1 again nothing; s2 the points of keyframe 2; s3 the 500 new ones
    assert calls == [N_PT, 300, points_of_kf2, 500]
