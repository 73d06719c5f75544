"""The map's edgelets and their keyframe measurements (Agility §4.1, §4.3, §5.2), owned by ``Map``.

Plain numpy columns, like the map's points: an edgelet is its world centre, unit direction (E-frame z) and unit
dark-to-light normal (E-frame x, ``ptam.edgelet.edgelet``), its source keyframe and a bad flag; edgelets are
never physically removed, so their indices are stable. A measurement is keyframe ``kf`` seeing edgelet
``edgelet`` as the image line through ``a`` with unit direction ``b`` (``perp(b)`` dark → light, §4.2).

Per keyframe the store also keeps §5.2's visibility table of the edgelets measured there: their ids and, per
simulated blur length (a column), visible / r_search / t_min, and the longest blur still measured. Rows are
appended as edgelets gain measurements, into spare capacity past a table's rows (doubled when full, so a table
of hundreds of rows × 33 blurs is not copied on every append); the rows a table holds are never changed (removing
rows makes new arrays), so a snapshot shares them safely.

The store knows nothing of edgelet geometry (``ptam.map`` sits below ``ptam.edgelet``); ``Map`` wraps every
mutation so that its ``version`` changes with it.
"""

from __future__ import annotations

import numpy as np

EDGELET_FIELDS = {
    "centre": (np.float64, (3,)),
    "direction": (np.float64, (3,)),
    "normal": (np.float64, (3,)),
    "source_kf": (np.int32, ()),
    "bad": (np.bool_, ()),
}
EDGELET_MEAS_FIELDS = {
    "kf": (np.int32, ()),
    "edgelet": (np.int32, ()),
    "a": (np.float64, (2,)),
    "b": (np.float64, (2,)),
}


class EdgeletStore:
    """Edgelet and measurement columns grown by ``columns`` (the map's capacity-doubling column type)."""

    def __init__(self, columns) -> None:
        self._e = columns(EDGELET_FIELDS)
        self._m = columns(EDGELET_MEAS_FIELDS)
        self.tables: dict[int, tuple[np.ndarray, ...]] = {}
        self._table_space: dict[int, tuple[np.ndarray, ...]] = {}  # each table's arrays with their spare rows

    @property
    def n_total(self) -> int:
        """All edgelets ever added, bad ones included."""
        return self._e.n

    @property
    def n_measurements(self) -> int:
        return self._m.n

    def view(self, name: str) -> np.ndarray:
        """Read-only view of an edgelet column (``centre`` …) or a measurement column (``meas_kf`` …)."""
        if name.startswith("meas_"):
            return self._m.view(name[len("meas_") :])
        return self._e.view(name)

    def add(self, centre, direction, normal, source_kf) -> np.ndarray:
        n = len(centre)
        return self._e.append(
            centre=centre, direction=direction, normal=normal, source_kf=source_kf, bad=np.zeros(n, bool)
        )

    def set(self, idx: np.ndarray, centre, direction, normal) -> None:
        for name, v in (("centre", centre), ("direction", direction), ("normal", normal)):
            self._e.data[name][idx] = v

    def add_measurements(self, kf, edgelet, a, b) -> np.ndarray:
        return self._m.append(kf=kf, edgelet=edgelet, a=a, b=b)

    def remove_measurements(self, mask: np.ndarray) -> None:
        """Drop the measurements where ``mask`` and their keyframes' visibility-table rows."""
        m = self._m
        gone_kf, gone_e = m.data["kf"][: m.n][mask], m.data["edgelet"][: m.n][mask]
        m.keep(~mask)
        for k in np.unique(gone_kf).tolist():  # one pass per keyframe that lost a measurement
            t = self.tables.get(k)
            if t is not None:
                self._set_table(k, tuple(a[~np.isin(t[0], gone_e[gone_kf == k])] for a in t))

    def _set_table(self, kf: int, rows: tuple[np.ndarray, ...]) -> None:
        for a in rows:
            a.setflags(write=False)
        self.tables[kf] = rows

    def mark_bad(self, idx: np.ndarray) -> None:
        """Flag edgelets bad and drop their measurements and visibility-table rows."""
        self._e.data["bad"][idx] = True
        gone = np.zeros(self._e.n, bool)
        gone[idx] = True
        self._m.keep(~gone[self._m.data["edgelet"][: self._m.n]])
        for k, t in list(self.tables.items()):
            keep = ~gone[t[0]]
            self.tables[k] = tuple(a[keep] for a in t)

    def append_table(self, kf: int, ids, visible, r_search, t_min, max_blur) -> None:
        """Add rows (edgelet ids, their per-blur visible / r_search / t_min, max blur) to keyframe ``kf``'s table."""
        new: tuple[np.ndarray, ...] = (np.asarray(ids, np.int64), np.asarray(visible, bool), np.asarray(r_search))
        new += (np.asarray(t_min), np.asarray(max_blur))
        old = self.tables.get(kf, ())
        n, m = (len(old[0]) if old else 0), len(new[0])
        space = self._table_space.get(kf)
        if space is None or not old or old[0].base is not space[0] or len(space[0]) < n + m:
            space = tuple(np.empty((max(n + m, 2 * n), *x.shape[1:]), x.dtype) for x in new)
            for s, o in zip(space, old):
                s[:n] = o
            self._table_space[kf] = space
        for s, x in zip(space, new):
            s[n : n + m] = x
        self._set_table(kf, tuple(s[: n + m] for s in space))

    def transform(self, R: np.ndarray, t: np.ndarray, scale: float) -> None:
        """X_new = R·(scale·X_old) + t for centres; directions and normals rotate."""
        e = self._e
        e.data["centre"][: e.n] = scale * e.data["centre"][: e.n] @ R.T + t
        for name in ("direction", "normal"):
            e.data[name][: e.n] = e.data[name][: e.n] @ R.T

    def snapshot_fields(self) -> dict:
        """Read-only copies for ``MapSnapshot``: ``edgelet_<column>`` and ``edgelet_meas_<column>``, and the
        visibility tables (a new dict of the immutable per-keyframe arrays)."""
        out = {f"edgelet_{k}": self._e.copy(k) for k in EDGELET_FIELDS}
        out.update({f"edgelet_meas_{k}": self._m.copy(k) for k in EDGELET_MEAS_FIELDS})
        out["edgelet_tables"] = dict(self.tables)
        return out
