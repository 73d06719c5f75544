"""The map store owned by the mapping thread: structure of arrays with capacity doubling (PTAM §4).

Only the mapper mutates a ``Map`` (through its methods, each of which bumps ``version``); everyone else reads
the :class:`MapSnapshot` it publishes. Keyframe i is ``keyframes[i]`` (so ``KeyFrame.id`` == i); its pose is
``kf_T_cw[i]`` and its level-L image ``kf_images[L][i]``. Points are never physically removed: a rejected point
is marked bad and loses its measurements, so point indices are stable for the map's lifetime. The properties
return read-only views of the live arrays, valid until the next mutation.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import PtamError
from .edgelet_store import EdgeletStore
from .keyframe import KeyFrame
from .snapshot import MapSnapshot, camera_centres

_POINT_FIELDS = {
    "X": (np.float64, (3,)),
    "normal": (np.float64, (3,)),
    "source_kf": (np.int32, ()),
    "source_level": (np.int8, ()),
    "source_xy": (np.float64, (2,)),
    "bad": (np.bool_, ()),
    "ray": (np.bool_, ()),
}
_MEAS_FIELDS = {
    "meas_kf": (np.int32, ()),
    "meas_pt": (np.int32, ()),
    "meas_xy": (np.float64, (2,)),
    "meas_level": (np.int8, ()),
    "meas_source": (np.int8, ()),
}

# Where a measurement came from (PTAM code ``Measurement::Source``): outliers of bundle adjustment get a
# second chance only when made by the tracker or the epipolar search; a point whose root (source-keyframe)
# measurement is an outlier is bad (PTAM §6.4).
SRC_ROOT, SRC_TRACKER, SRC_EPIPOLAR, SRC_REFIND = 0, 1, 2, 3


class _Columns:
    """Named arrays sharing one length, grown by doubling the capacity."""

    def __init__(self, spec: dict):
        self.n = 0
        self.data = {k: np.zeros((0, *shape), dtype) for k, (dtype, shape) in spec.items()}

    def reserve(self, extra: int) -> None:
        need = self.n + extra
        cap = len(next(iter(self.data.values())))
        if need <= cap:
            return
        cap = max(need, 2 * cap, 16)
        for k, a in self.data.items():
            b = np.zeros((cap, *a.shape[1:]), a.dtype)
            b[: self.n] = a[: self.n]
            self.data[k] = b

    def append(self, **values) -> np.ndarray:
        m = len(next(iter(values.values())))
        self.reserve(m)
        for k, v in values.items():
            self.data[k][self.n : self.n + m] = v
        idx = np.arange(self.n, self.n + m)
        self.n += m
        return idx

    def keep(self, mask: np.ndarray) -> None:
        k = int(mask.sum())
        for a in self.data.values():
            a[:k] = a[: self.n][mask]
        self.n = k

    def view(self, name: str) -> np.ndarray:
        v = self.data[name][: self.n]
        v.setflags(write=False)
        return v

    def copy(self, name: str) -> np.ndarray:
        c = self.data[name][: self.n].copy()
        c.setflags(write=False)
        return c


def _rows(name: str, a, n: int, shape: tuple, dtype) -> np.ndarray:
    a = np.asarray(a, dtype=dtype)
    if a.ndim == len(shape):
        a = np.broadcast_to(a, (n, *shape))
    if a.shape != (n, *shape):
        raise PtamError(f"map: {name} must have shape {(n, *shape)}, got {a.shape}")
    return a


class Map:
    def __init__(self) -> None:
        self.keyframes: list[KeyFrame] = []
        self._kf_T_cw = np.zeros((0, 4, 4))
        self._kf_images: list[np.ndarray] = []
        self._points = _Columns(_POINT_FIELDS)
        self._meas = _Columns(_MEAS_FIELDS)
        self.edgelets = EdgeletStore(_Columns)  # Agility §4: read through its views, mutate through Map
        self.version = 0
        self._snapshot: MapSnapshot | None = None

    # -- keyframes ---------------------------------------------------------------------------------------
    @property
    def n_keyframes(self) -> int:
        return len(self.keyframes)

    @property
    def next_keyframe_id(self) -> int:
        return len(self.keyframes)

    def add_keyframe(self, kf: KeyFrame, T_cw: np.ndarray) -> int:
        """Append a keyframe with its pose; returns its index, which must equal ``kf.id``."""
        i = len(self.keyframes)
        if kf.id != i:
            raise PtamError(f"map: keyframe id {kf.id} must equal its index {i} (use Map.next_keyframe_id)")
        T_cw = _rows("T_cw", T_cw, 1, (4, 4), np.float64)[0]
        levels = kf.pyramid.levels
        if self._kf_images and [im.shape for im in levels] != [s.shape[1:] for s in self._kf_images]:
            raise PtamError("map: keyframe pyramid shapes differ from the map's keyframes")
        cap = len(self._kf_T_cw)
        if i == cap:
            cap = max(2 * cap, 8)
            T = np.zeros((cap, 4, 4))
            T[:i] = self._kf_T_cw[:i]
            self._kf_T_cw = T
            # New stacks: snapshots keep views of the old ones, whose first i entries never change.
            self._kf_images = (
                [np.zeros((cap, *im.shape), np.uint8) for im in levels]
                if i == 0
                else [np.concatenate([s[:i], np.zeros((cap - i, *s.shape[1:]), np.uint8)]) for s in self._kf_images]
            )
        self._kf_T_cw[i] = T_cw
        for stack, im in zip(self._kf_images, levels):
            stack[i] = im
        self.keyframes.append(kf)
        self._changed()
        return i

    @property
    def kf_T_cw(self) -> np.ndarray:
        v = self._kf_T_cw[: self.n_keyframes]
        v.setflags(write=False)
        return v

    @property
    def kf_images(self) -> tuple[np.ndarray, ...]:
        return tuple(self._frozen_stack(s) for s in self._kf_images)

    @property
    def camera_centres(self) -> np.ndarray:
        return camera_centres(self.kf_T_cw)

    def keyframes_with_baseline(self, k: int, exclude=()) -> np.ndarray:
        """The keyframes that can have a baseline to keyframe k, nearest by camera centre first: not k, not in
        ``exclude``, not panorama keyframes (Gauglitz et al. §4.3)."""
        c = self.camera_centres
        d = np.linalg.norm(c - c[k], axis=1)
        d[[k, *exclude]] = np.inf
        d[KeyFrame.panorama_flags(self.keyframes)] = np.inf
        order = np.argsort(d, kind="stable")
        return order[np.isfinite(d[order])]

    def nearest_with_baseline(self, k: int, exclude=()) -> int:
        """The first of ``keyframes_with_baseline``; -1 when there is none."""
        js = self.keyframes_with_baseline(k, exclude)
        return int(js[0]) if len(js) else -1

    def set_poses(self, indices, T_cw) -> None:
        idx = self._check_indices("keyframe", indices, self.n_keyframes)
        self._kf_T_cw[idx] = _rows("T_cw", T_cw, len(idx), (4, 4), np.float64)
        self._changed()

    # -- points ------------------------------------------------------------------------------------------
    @property
    def n_points_total(self) -> int:
        """All points ever added, bad ones included (the length of the point arrays)."""
        return self._points.n

    def add_points(self, X, normal, source_kf, source_level, source_xy, ray=False) -> np.ndarray:
        """Append points; ``normal`` is the unit patch normal in the world frame. ``ray``: panorama features
        (Gauglitz et al. §3.2), rays from their source keyframe's centre whose depth is unknown; X is a point on
        the ray at the keyframe's scene depth, for drawing and visibility. Returns their indices."""
        X = np.asarray(X, dtype=np.float64)
        if X.ndim != 2:
            raise PtamError(f"map: X must have shape (M, 3), got {X.shape}")
        n = len(X)
        values = dict(
            X=_rows("X", X, n, (3,), np.float64),
            normal=_rows("normal", normal, n, (3,), np.float64),
            source_kf=_rows("source_kf", source_kf, n, (), np.int32),
            source_level=_rows("source_level", source_level, n, (), np.int8),
            source_xy=_rows("source_xy", source_xy, n, (2,), np.float64),
            bad=np.zeros(n, bool),
            ray=np.broadcast_to(np.asarray(ray, dtype=bool), (n,)).copy(),
        )
        self._check_indices("source keyframe", values["source_kf"], self.n_keyframes)
        idx = self._points.append(**values)
        self._changed()
        return idx

    def set_points(self, indices, X) -> None:
        idx = self._check_indices("point", indices, self._points.n)
        self._points.data["X"][idx] = _rows("X", X, len(idx), (3,), np.float64)
        self._changed()

    def place_rays(self, indices, X) -> None:
        """Panorama features that gained depth (Gauglitz et al. §4.3) become map points at X (M, 3)."""
        self.set_points(indices, X)
        self._points.data["ray"][np.asarray(indices, dtype=np.int64)] = False

    def set_normals(self, indices, normal) -> None:
        """Replace the unit patch normals (world frame) of points ``indices`` (Gauglitz et al. §5.4 estimates)."""
        idx = self._check_indices("point", indices, self._points.n)
        self._points.data["normal"][idx] = _rows("normal", normal, len(idx), (3,), np.float64)
        self._changed()

    def transform(self, T_new_old: np.ndarray, scale: float = 1.0) -> None:
        """Move the whole map to new world coordinates X_new = T_new_old·(scale·X_old): points, normals and
        keyframe poses together (PTAM code ``ApplyGlobalTransformationToMap`` / ``ApplyGlobalScaleToMap``)."""
        T_new_old = np.asarray(T_new_old, dtype=np.float64)
        R, t = T_new_old[:3, :3], T_new_old[:3, 3]
        P = self._points
        P.data["X"][: P.n] = scale * P.data["X"][: P.n] @ R.T + t
        P.data["normal"][: P.n] = P.data["normal"][: P.n] @ R.T
        self.edgelets.transform(R, t, scale)
        T = self._kf_T_cw[: self.n_keyframes]
        T[:, :3, 3] *= scale
        T_old_new = np.eye(4)
        T_old_new[:3, :3] = R.T
        T_old_new[:3, 3] = -R.T @ t
        T[:] = T @ T_old_new
        self._changed()

    def mark_bad(self, point_indices) -> None:
        """Flag points as bad and drop all their measurements (PTAM §6.4: bad points are removed)."""
        idx = self._check_indices("point", point_indices, self._points.n)
        self._points.data["bad"][idx] = True
        gone = np.zeros(self._points.n, bool)
        gone[idx] = True
        self._meas.keep(~gone[self._meas.data["meas_pt"][: self._meas.n]])
        self._changed()

    # -- measurements ------------------------------------------------------------------------------------
    @property
    def n_measurements(self) -> int:
        return self._meas.n

    def add_measurements(self, kf, pt, xy, level, source=SRC_TRACKER) -> np.ndarray:
        """Append measurements of points ``pt`` in keyframes ``kf`` at level-0 pixels ``xy`` found on pyramid
        level ``level`` by ``source`` (SRC_*). One measurement per (keyframe, point) pair is the caller's
        responsibility."""
        pt = np.asarray(pt, dtype=np.int32).reshape(-1)
        n = len(pt)
        values = dict(
            meas_kf=_rows("kf", kf, n, (), np.int32),
            meas_pt=pt,
            meas_xy=_rows("xy", xy, n, (2,), np.float64),
            meas_level=_rows("level", level, n, (), np.int8),
            meas_source=_rows("source", source, n, (), np.int8),
        )
        self._check_indices("keyframe", values["meas_kf"], self.n_keyframes)
        self._check_indices("point", pt, self._points.n)
        idx = self._meas.append(**values)
        self._changed()
        return idx

    def remove_measurements(self, mask) -> None:
        """Drop the measurements where ``mask`` (one bool per current measurement) is true."""
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != (self._meas.n,):
            raise PtamError(f"map: measurement mask must have shape ({self._meas.n},), got {mask.shape}")
        self._meas.keep(~mask)
        self._changed()

    # -- edgelets (Agility §4) ---------------------------------------------------------------------------
    def add_edgelets(self, centre, direction, normal, source_kf) -> np.ndarray:
        """Append edgelets (world centre, unit direction, unit dark-to-light normal, each (M, 3)); their ids."""
        centre = np.asarray(centre, dtype=np.float64).reshape(-1, 3)
        n = len(centre)
        src = _rows("source_kf", source_kf, n, (), np.int32)
        self._check_indices("source keyframe", src, self.n_keyframes)
        d, x = (_rows(k, v, n, (3,), np.float64) for k, v in (("direction", direction), ("normal", normal)))
        idx = self.edgelets.add(centre, d, x, src)
        self._changed()
        return idx

    def set_edgelets(self, indices, centre, direction, normal) -> None:
        idx = self._check_indices("edgelet", indices, self.edgelets.n_total)
        n = len(idx)
        self.edgelets.set(idx, *(_rows("edgelet", v, n, (3,), np.float64) for v in (centre, direction, normal)))
        self._changed()

    def add_edgelet_measurements(self, kf, edgelet, a, b) -> np.ndarray:
        """Keyframes ``kf`` measured edgelets ``edgelet`` as the image lines a + λb (level-0 px, (M, 2))."""
        e = np.asarray(edgelet, dtype=np.int32).reshape(-1)
        n = len(e)
        k = _rows("kf", kf, n, (), np.int32)
        self._check_indices("keyframe", k, self.n_keyframes)
        self._check_indices("edgelet", e, self.edgelets.n_total)
        idx = self.edgelets.add_measurements(
            k, e, _rows("a", a, n, (2,), np.float64), _rows("b", b, n, (2,), np.float64)
        )
        self._changed()
        return idx

    def add_edgelet_table_rows(self, kf: int, ids, visible, r_search, t_min, max_blur) -> None:
        """Agility §5.2: visibility-table rows of edgelets ``ids`` measured in keyframe ``kf``."""
        self._check_indices("keyframe", kf, self.n_keyframes)
        self._check_indices("edgelet", ids, self.edgelets.n_total)
        self.edgelets.append_table(int(kf), ids, visible, r_search, t_min, max_blur)
        self._changed()

    def remove_edgelet_measurements(self, mask) -> None:
        """Drop the edgelet measurements where ``mask`` (one bool per current one) and their table rows (§5.2)."""
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != (self.edgelets.n_measurements,):
            raise PtamError(f"map: edgelet measurement mask must have shape ({self.edgelets.n_measurements},)")
        self.edgelets.remove_measurements(mask)
        self._changed()

    def mark_edgelets_bad(self, indices) -> None:
        self.edgelets.mark_bad(self._check_indices("edgelet", indices, self.edgelets.n_total))
        self._changed()

    def __getattr__(self, name: str):
        # Read-only views of the point and measurement columns: map.X, map.meas_kf, ...
        if name in _POINT_FIELDS:
            return self._points.view(name)
        if name in _MEAS_FIELDS:
            return self._meas.view(name)
        raise AttributeError(name)

    # -- snapshot ----------------------------------------------------------------------------------------
    def snapshot(self) -> MapSnapshot:
        """An immutable copy of the current map (cached until the next change)."""
        if self._snapshot is None or self._snapshot.version != self.version:
            P, M = self._points, self._meas
            T = self._kf_T_cw[: self.n_keyframes].copy()
            T.setflags(write=False)
            good = np.flatnonzero(~P.data["bad"][: P.n])
            good.setflags(write=False)
            columns: dict[str, Any] = {k: P.copy(k) for k in _POINT_FIELDS}
            columns.update({k: M.copy(k) for k in _MEAS_FIELDS}, **self.edgelets.snapshot_fields())
            self._snapshot = MapSnapshot(
                version=self.version,
                keyframes=tuple(self.keyframes),
                kf_T_cw=T,
                kf_images=tuple(self._frozen_stack(s) for s in self._kf_images),
                good_point_indices=good,
                **columns,
            )
        return self._snapshot

    # -- helpers -----------------------------------------------------------------------------------------
    def _frozen_stack(self, stack: np.ndarray) -> np.ndarray:
        v = stack[: self.n_keyframes]
        v.setflags(write=False)
        return v

    def _changed(self) -> None:
        self.version += 1

    @staticmethod
    def _check_indices(what: str, indices, n: int) -> np.ndarray:
        idx = np.asarray(indices, dtype=np.int64).reshape(-1)
        if idx.size and (idx.min() < 0 or idx.max() >= n):
            raise PtamError(f"map: {what} index out of range [0, {n}): {idx.min()}..{idx.max()}")
        return idx
