"""The map's edgelets measured in keyframes, with their visibility-table rows (Agility §4.2, §4.4, §5.2).

§4.4: edgelets are added "with at least three measurements – one each from the source, target, and check keyframes
– and more measurements are attempted in all old keyframes and all keyframes subsequently added". The edgelet job
(``edgelet_mapping``) measures the map's edgelets in each new keyframe (``unmeasured``), as PTAM measures its
points in a new keyframe while adding it; the new edgelets are measured in the old keyframes later, when the mapper
is idle (``measure_newly_made``), as PTAM code's ``ReFindNewlyMade`` re-finds new points there after the local
bundle adjustment. Every measurement adds its row to its keyframe's visibility table (§5.2), which the tracker
reads: one table build per keyframe (``build_tables``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..edgelet import Edgelets, build_visibility_table, measure_in_keyframe, perp, project_edgelets

if TYPE_CHECKING:
    from ..camera.model import CameraModel
    from ..config import Config
    from ..map.map import Map

Found = tuple[int, np.ndarray, np.ndarray, np.ndarray]  # keyframe, edgelet ids, measured lines a, b (§4.2)


def keyframe_image(m: Map, k: int) -> np.ndarray:
    return m.keyframes[k].pyramid.levels[0]


def _inside(uv: np.ndarray, shape: tuple, border: float) -> np.ndarray:
    h, w = shape
    return (uv[:, 0] >= border) & (uv[:, 1] >= border) & (uv[:, 0] <= w - 1 - border) & (uv[:, 1] <= h - 1 - border)


def measured_in(m: Map, camera: CameraModel, cfg: Config, k: int, ids: np.ndarray) -> Found:
    """Edgelets ``ids`` projected into keyframe k and measured there (§4.2): the found ones and their lines."""
    e = cfg.edgelets
    none = (k, ids[:0], np.zeros((0, 2)), np.zeros((0, 2)))
    if len(ids) == 0:
        return none
    ed = Edgelets(m.edgelets.view("centre")[ids], m.edgelets.view("direction")[ids], m.edgelets.view("normal")[ids])
    p = project_edgelets(camera, m.kf_T_cw[k], ed)
    img = keyframe_image(m, k)
    sel = np.flatnonzero(p.valid & _inside(p.centre, img.shape, e.candidate_border_px))
    if len(sel) == 0:
        return none
    meas = measure_in_keyframe(img, p.centre[sel], p.direction[sel], p.normal[sel], e)
    return k, ids[sel[meas.ok]], meas.a[meas.ok], meas.b[meas.ok]


def record(m: Map, found: list[Found], tables: list[Found]) -> int:
    """Add the measurements (keyframe, edgelet ids, lines a, b) of several keyframes to the map at once; their
    visibility-table rows (§5.2) wait in ``tables`` for ``build_tables``. Returns how many were added."""
    found = [f for f in found if len(f[1])]
    if not found:
        return 0
    kf = np.concatenate([np.full(len(ids), k) for k, ids, _, _ in found])
    m.add_edgelet_measurements(kf, *(np.concatenate([f[i] for f in found]) for i in (1, 2, 3)))
    tables.extend(found)
    return len(kf)


def build_tables(m: Map, cfg: Config, found: list[Found]) -> None:
    """The visibility-table rows (§5.2) of the measurements ``found``: one table build per keyframe, its rows in the
    order they were measured (a job measures in some keyframes several times; each row depends on its own
    measurement only)."""
    for k in dict.fromkeys(f[0] for f in found):  # keyframes in the order first measured in
        ids, a, b = (np.concatenate([f[i] for f in found if f[0] == k]) for i in (1, 2, 3))
        t = build_visibility_table(keyframe_image(m, k), a, perp(b), cfg.edgelets)
        m.add_edgelet_table_rows(k, ids, t.visible, t.r_search, t.t_min, t.max_blur)


def rebuild_visibility_tables(m: Map, cfg: Config, first_kf: int = 0) -> None:
    """§5.2's tables of keyframes ``first_kf`` on, which have none (read from a map file, or merged from another
    track: they derive from the keyframe images and the edgelet measurements, with the current config's blur
    lengths)."""
    st = m.edgelets
    kf = st.view("meas_kf")
    found = [
        (k, *(st.view(f"meas_{c}")[kf == k] for c in ("edgelet", "a", "b")))
        for k in np.unique(kf[kf >= first_kf]).tolist()
    ]
    build_tables(m, cfg, found)


def unmeasured(m: Map, k: int) -> np.ndarray:
    """Good edgelets that keyframe k does not measure."""
    seen = np.zeros(m.edgelets.n_total, bool)
    seen[m.edgelets.view("meas_edgelet")[m.edgelets.view("meas_kf") == k]] = True
    return np.flatnonzero(~seen & ~m.edgelets.view("bad"))


def measure_newly_made(m: Map, camera: CameraModel, cfg: Config, ids: np.ndarray, start: int, abort) -> int:
    """§4.4's "more measurements are attempted in all old keyframes" for the new edgelets ``ids``: each keyframe
    from ``start`` on measures those it sees and does not measure yet, and adds their visibility-table rows (§5.2).
    The mapper runs it when idle, as PTAM code's ``ReFindNewlyMade`` searches old keyframes for new points, so a
    queued keyframe (``abort()``, asked between keyframes) waits for no more than one keyframe's measurements;
    returns the keyframe to resume from, or -1 when every keyframe was searched."""
    ids = ids[~m.edgelets.view("bad")[ids]]
    if len(ids) == 0:
        return -1
    seen = _in_view(m, camera, ids, cfg.edgelets.candidate_border_px) & ~_measures(m, ids)
    for j in range(start, len(seen)):
        if not seen[j].any():
            continue
        if abort():
            return j
        tables: list[Found] = []
        record(m, [measured_in(m, camera, cfg, j, ids[seen[j]])], tables)
        build_tables(m, cfg, tables)
    return -1


def _measures(m: Map, ids: np.ndarray) -> np.ndarray:
    """(K, N): whether keyframe k measures edgelet ``ids[n]``."""
    st = m.edgelets
    col = np.full(st.n_total, -1)
    col[ids] = np.arange(len(ids))
    c = col[st.view("meas_edgelet")]
    out = np.zeros((m.n_keyframes, len(ids)), bool)
    out[st.view("meas_kf")[c >= 0], c[c >= 0]] = True
    return out


def _in_view(m: Map, camera: CameraModel, ids: np.ndarray, border: float) -> np.ndarray:
    """(K, N): whether edgelet ``ids[n]``'s centre projects inside keyframe k's image, by ``border`` px (the test
    ``measured_in`` starts with), for every keyframe at once."""
    T = m.kf_T_cw
    Xc = np.einsum("kij,nj->kni", T[:, :3, :3], m.edgelets.view("centre")[ids]) + T[:, None, :3, 3]
    flat = Xc.reshape(-1, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        inside = camera.valid(flat) & camera.in_image(camera.project(flat), border)
    return inside.reshape(len(T), len(ids))
