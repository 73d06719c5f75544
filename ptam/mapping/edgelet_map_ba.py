"""The mapper's side of bundle adjustment on edgelets (Agility §4.4): what to adjust, and what to keep after.

§4.4: "Whenever information is added to the map, the position of all edgelets, points and keyframes is optimised
through bundle adjustment." With ``edgelets.enabled`` the mapper's local and global adjustments (PTAM §6.3) take
the map's edgelets: global BA adjusts every good edgelet, local BA those measured in a keyframe it adjusts (the
edgelets' Z of PTAM eq. 11), with all their measurements, the other keyframes held fixed as for points.

Outliers are handled as PTAM §6.4 handles a point's: an edgelet whose source-keyframe measurement is an outlier,
or that had no more than ``mapper.outlier_min_good_measurements`` measurements, is marked bad; otherwise the
outlying measurement (and its visibility-table row, §5.2) is dropped. There is no second-chance search: an
edgelet is measured again in every keyframe added later (§4.4) and in all old keyframes after it is made.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..edgelet import EdgeletObservations, Edgelets
from .bundle_inputs import EdgeletBundleInput

if TYPE_CHECKING:
    from ..config import Config
    from ..map.map import Map
    from .bundle import BundleResult


def edgelet_ba_input(m: Map, cfg: Config, adjust_keyframes: np.ndarray | None) -> EdgeletBundleInput | None:
    """The map's edgelets for an adjustment of the keyframes ``adjust_keyframes`` (local BA) or of all (None);
    None when edgelets are off or none is measured."""
    st = m.edgelets
    if not cfg.edgelets.enabled or st.n_measurements == 0:
        return None
    kf, e = st.view("meas_kf"), st.view("meas_edgelet")
    adjust = ~st.view("bad")
    if adjust_keyframes is not None:
        near = np.zeros(st.n_total, bool)
        near[e[adjust_keyframes[kf]]] = True
        adjust &= near
    ed = Edgelets(st.view("centre"), st.view("direction"), st.view("normal"))
    obs = EdgeletObservations(kf, e, st.view("meas_a"), st.view("meas_b"))
    return EdgeletBundleInput(ed, obs, cfg.edgelets, adjust)


def keep_edgelets(m: Map, inp: EdgeletBundleInput | None, res: BundleResult) -> None:
    """Write the adjusted edgelets of an accepted adjustment back into the map."""
    if inp is None or res.edgelets is None:
        return
    ids = np.flatnonzero(inp.adjust_mask)
    m.set_edgelets(ids, res.edgelets.centre[ids], res.edgelets.direction[ids], res.edgelets.normal[ids])


def handle_edgelet_outliers(m: Map, cfg: Config, outliers: np.ndarray) -> None:
    """PTAM §6.4 for edgelets: ``outliers`` index the map's edgelet measurements (as given to the adjustment)."""
    if len(outliers) == 0:
        return
    st = m.edgelets
    kf, e = st.view("meas_kf")[outliers], st.view("meas_edgelet")[outliers]
    count = np.bincount(st.view("meas_edgelet"), minlength=st.n_total)
    bad = (count[e] <= cfg.mapper.outlier_min_good_measurements) | (kf == st.view("source_kf")[e])
    mask = np.zeros(st.n_measurements, bool)
    mask[outliers[~bad]] = True
    m.remove_edgelet_measurements(mask)
    if bad.any():
        m.mark_edgelets_bad(np.unique(e[bad]))
