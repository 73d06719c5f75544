"""The mapper's edgelet job: new edgelets for a new keyframe, and the map's edgelets measured in it (Agility §4.3).

``integrate_keyframe`` is the mapper's one edgelet job per (non-panorama) keyframe k:

1. the map's edgelets are projected into k and measured there (§4.2; §4.4: "more measurements are attempted in
   ... all keyframes subsequently added"); the bundle adjustment that follows the job moves them on the new
   measurements (§4.4), as it moves points;
2. candidates are extracted in k away from the edgelets it measures (``extract_candidates``);
3. each candidate's viewing ray, cut to k's depth prior as PTAM cuts a point's (``epipolar.py``: z in
   [max(w, mean − σ), min(40·w, mean + σ)], w the initial baseline), is projected into the target keyframe t
   as a piecewise-linear curve through the lens, evenly spaced in inverse depth, and sampled every
   ``epipolar_step_px``; every run of maximal edgels (Canny without hysteresis) it crosses is a match;
4. matches are culled by polarity (the light side of the source line's back-projected plane must project to the
   light side of the target gradient) and by the angle between the edge and the epipolar curve; the rest are
   measured in t (§4.2), triangulated (``triangulate_edgelets``) and checked in a third keyframe, for each
   hypothesis the nearest that can tell its depth (``edgelet_check``); a candidate becomes an edgelet only if
   exactly one hypothesis passes (hypotheses whose
   target measurements lie within ``hypothesis_merge_px`` are one);
5. new edgelets are refined on their three measurements with the poses fixed (the edgelet blocks of §4.4);

and every measurement adds its row to the keyframe's visibility table (§5.2), which the tracker reads (at the end of
the job, one table build per keyframe). §4.4's further measurements of the new edgelets "in all old keyframes" are
not part of the job: the mapper makes them when idle (``edgelet_measurements.measure_newly_made``), as PTAM code
re-finds new points in old keyframes (``ReFindNewlyMade``) outside adding them. §9.2's 20 ms for "edge extraction
and adding edgelets", "twice as long as it takes to add points", thereby cover what PTAM's adding points covers:
the measurements in the new keyframe and the search for new features.
Candidates whose back-projected plane nearly contains t's centre (§4.3's aperture problem) are attempted again,
steps 3-5, with the keyframe that frees most of them from it (``edgelet_aperture``).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from ..edgelet import (
    EdgeletObservations,
    Edgelets,
    LineMeasurements,
    extract_candidates,
    gradient_at,
    line_rays,
    measure_in_keyframe,
    refine_edgelets,
    triangulate_edgelets,
)
from ..geometry import se3
from .edgelet_aperture import aperture_retry
from .edgelet_check import check_keyframes, verify_in_check_keyframes
from .edgelet_cull_kernels import polarity_cull
from .edgelet_epipolar_kernels import curve_hits, curve_vertices
from .edgelet_images import EdgeImages
from .edgelet_measurements import Found, build_tables, keyframe_image, measured_in, record, unmeasured

if TYPE_CHECKING:
    from ..camera.model import CameraModel
    from ..config import Config
    from ..map.map import Map


@dataclass(frozen=True)
class EdgeletJob:
    """What one keyframe's edgelet job did: measurements of existing edgelets, candidates, matches measured
    in the target, edgelets added, its wall time (ms) and that of its last step, the §5.2 visibility tables
    (``tables_ms``; §9.2's 20 ms name edge extraction and adding edgelets); and how many candidates were left
    after each step (``FUNNEL``; a candidate counts once, with the target or with the aperture retry's): with a
    match on the epipolar curve, one kept by the polarity and angle culls, one measured in the target, one whose
    planes meet at the gate or more, one that passed the check keyframe."""

    remeasured: int = 0
    candidates: int = 0
    hypotheses: int = 0
    added: int = 0
    ms: float = 0.0
    matched: int = 0
    kept: int = 0
    measured: int = 0
    triangulated: int = 0
    verified: int = 0
    tables_ms: float = 0.0

    FUNNEL: ClassVar[tuple[str, ...]] = (
        "candidates",
        "matched",
        "kept",
        "measured",
        "triangulated",
        "verified",
        "added",
    )


@dataclass(frozen=True)
class _Hits:
    """Matches on the epipolar curves: candidate index, target pixel, source depth z, unit curve tangent."""

    cand: np.ndarray
    uv: np.ndarray
    z: np.ndarray
    tangent: np.ndarray


def _keep(h: _Hits, mask: np.ndarray) -> _Hits:
    return _Hits(h.cand[mask], h.uv[mask], h.z[mask], h.tangent[mask])


def _take(m: LineMeasurements, idx) -> LineMeasurements:
    return LineMeasurements(*(getattr(m, f.name)[idx] for f in fields(m)))


def integrate_keyframe(
    m: Map, camera: CameraModel, cfg: Config, k: int, t: int, images: EdgeImages | None = None
) -> EdgeletJob:
    """The edgelet job for new keyframe k with target keyframe t (the mapper's closest keyframe); ``images``: the
    mapper's keyframe images kept from earlier jobs, if any."""
    start = time.perf_counter()
    tables: list[Found] = []
    job = _integrate(m, camera, cfg, (k, t), images if images is not None else EdgeImages(cfg.edgelets), tables)
    built = time.perf_counter()
    build_tables(m, cfg, tables)
    end = time.perf_counter()
    return dataclasses.replace(job, ms=1e3 * (end - start), tables_ms=1e3 * (end - built))


def _integrate(
    m: Map, camera: CameraModel, cfg: Config, kt: tuple[int, int], images: EdgeImages, tables: list[Found]
) -> EdgeletJob:
    k, t = kt
    remeasured = record(m, [measured_in(m, camera, cfg, k, unmeasured(m, k))], tables)
    if m.nearest_with_baseline(k, exclude=(t,)) < 0:  # no keyframe to check hypotheses in
        return EdgeletJob(remeasured)
    e = cfg.edgelets
    measured = m.edgelets.view("meas_kf") == k
    existing = m.edgelets.view("meas_a")[measured]
    cand = extract_candidates(keyframe_image(m, k), e, existing, images.smoothed(m, k))
    if len(cand) == 0:
        return EdgeletJob(remeasured)
    src = measure_in_keyframe(keyframe_image(m, k), cand.centre, cand.direction, cand.normal, e)
    src = _take(src, np.flatnonzero(src.ok))
    hypotheses, made, left = _triangulate_with(m, camera, cfg, (k, t), src, (images, tables), ())
    added = len(made)
    t2, sel = aperture_retry(m, camera, e, k, t, src) if e.aperture_retry else (-1, made[:0])
    # The retry's hypotheses are checked beside both targets: in t every hypothesis of a candidate the retry
    # takes up projects onto one image line (its plane through k's centre nearly holds t's centre).
    if t2 >= 0 and m.nearest_with_baseline(k, exclude=(t, t2)) >= 0:
        sel = np.setdiff1d(sel, made)  # candidates that became edgelets with t despite the prediction
        h2, made2, left2 = _triangulate_with(m, camera, cfg, (k, t2), _take(src, sel), (images, tables), (t,))
        hypotheses, added = hypotheses + h2, added + len(made2)
        left = tuple(np.union1d(a, sel[b]) for a, b in zip(left, left2))
    matched, kept, measured, triangulated, verified = (len(x) for x in left)
    return EdgeletJob(
        remeasured,
        len(src.a),
        hypotheses,
        added,
        matched=matched,
        kept=kept,
        measured=measured,
        triangulated=triangulated,
        verified=verified,
    )


def _triangulate_with(
    m: Map,
    camera: CameraModel,
    cfg: Config,
    kt: tuple[int, int],
    src: LineMeasurements,
    images_tables: tuple[EdgeImages, list[Found]],
    not_checks: tuple[int, ...],
) -> tuple[int, np.ndarray, tuple[np.ndarray, ...]]:
    """Steps 3-5 for source candidates ``src`` of keyframe k with target t (``kt``), checked in neither t nor
    ``not_checks`` (``edgelet_check``), with the job's keyframe ``images`` and pending ``tables`` rows: returns
    the hypotheses measured in t, the candidates that became edgelets, and the candidates left after each step
    (``EdgeletJob``'s matched, kept, measured, triangulated, verified)."""
    k, t = kt
    images, tables = images_tables
    e = cfg.edgelets
    sm_t = images.smoothed(m, t)  # Canny's input and the polarity gradient's, for this target
    hits = _epipolar_hits(m, camera, cfg, (k, t), src, images.maximal(m, t))
    matched = hits.cand
    hits = _cull(m, camera, k, t, src, hits, sm_t, e)
    kept = hits.cand
    tgt = _measure_hits(m, t, hits, sm_t, e)
    hits, tgt = _keep(hits, tgt.ok), _take(tgt, tgt.ok)
    T = m.kf_T_cw
    tri = triangulate_edgelets(camera, T[k], _take(src, hits.cand), T[t], tgt, e)
    checks = check_keyframes(m, camera, e, k, (t, *not_checks), tri.edgelets)
    ver = verify_in_check_keyframes(m, camera, e, checks, tri.edgelets)
    one = _single_hypotheses(hits.cand, tgt.a, tri.ok & ver.ok, e.hypothesis_merge_px)
    meas = (_take(src, hits.cand[one]), tgt, ver)
    made = _add(m, camera, cfg, (k, t, checks[one]), tri.edgelets.subset(one), meas, (one, tables))
    stages = (matched, kept, hits.cand, hits.cand[tri.ok], hits.cand[tri.ok & ver.ok])
    return len(hits.cand), hits.cand[one][made], tuple(np.unique(x) for x in stages)


def _depth_range(m: Map, cfg: Config, k: int) -> tuple[float, float]:
    kf = m.keyframes[k]
    w = cfg.init.baseline_m
    near = max(w, kf.scene_depth_mean - kf.scene_depth_sigma)
    return near, min(cfg.mapper.epipolar_far_depth_mult * w, kf.scene_depth_mean + kf.scene_depth_sigma)


def _epipolar_hits(
    m: Map, camera: CameraModel, cfg: Config, kt: tuple[int, int], src: LineMeasurements, maximal: np.ndarray
) -> _Hits:
    """Runs of ``maximal`` edgels (keyframe t's, dilated) along each candidate's epipolar curve in t (step 3)."""
    k, t = kt
    e = cfg.edgelets
    near, far = _depth_range(m, cfg, k)
    z = 1.0 / np.linspace(1.0 / near, 1.0 / far, e.epipolar_vertices) if far > near else np.zeros(0)
    n, v = len(src.a), len(z)
    if n == 0 or v < 2:
        return _Hits(np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2)))
    ray = np.concatenate([camera.unproject(src.a), np.ones((n, 1))], axis=1)
    T_ts = m.kf_T_cw[t] @ se3.inv(m.kf_T_cw[k])
    max_len = float(np.hypot(*keyframe_image(m, t).shape))  # no piece longer than the image's diagonal
    uv, seg_ok, length = curve_vertices(camera.kernel_params(), T_ts, ray, z, max_len)
    cand, pts, inv_z, tangent = curve_hits(
        uv, seg_ok, length, 1.0 / z, float(e.epipolar_step_px), maximal, float(e.candidate_border_px)
    )
    return _Hits(cand, pts, 1.0 / inv_z, tangent)


def _cull(
    m: Map, camera: CameraModel, k: int, t: int, src: LineMeasurements, hits: _Hits, sm_t: np.ndarray, e
) -> _Hits:
    """Step 4's heuristics: the target gradient must have the candidate's polarity and cross the epipolar curve
    at no less than ``epipolar_min_angle_deg`` (``edgelet_cull_kernels``)."""
    if len(hits.cand) == 0:
        return hits
    T = m.kf_T_cw
    keep = polarity_cull(
        camera.kernel_params(),
        T[k],
        T[t],
        line_rays(camera, src.a[hits.cand], src.b[hits.cand]),
        hits.z,
        src.b[hits.cand],
        gradient_at(sm_t, hits.uv),
        np.ascontiguousarray(hits.tangent),
        float(np.sin(np.deg2rad(e.epipolar_min_angle_deg))),
    )
    return _keep(hits, keep)


def _measure_hits(m: Map, t: int, hits: _Hits, sm_t: np.ndarray, e) -> LineMeasurements:
    """§4.2 measurements in t at the matches, along the edge their gradient shows (perp(b) dark → light)."""
    img = keyframe_image(m, t)
    n_hat = gradient_at(sm_t, hits.uv) if len(hits.cand) else np.zeros((0, 2))
    n_hat = n_hat / np.maximum(np.linalg.norm(n_hat, axis=1), np.finfo(float).tiny)[:, None]
    direction = np.stack([n_hat[:, 1], -n_hat[:, 0]], axis=1)  # perp(direction) = n_hat
    return measure_in_keyframe(img, hits.uv, direction, n_hat, e)


def _single_hypotheses(cand: np.ndarray, tgt_a: np.ndarray, ok: np.ndarray, merge_px: float) -> np.ndarray:
    """Indices of the passing hypotheses that are their candidate's only one (§4.3), duplicates merged."""
    idx = np.flatnonzero(ok)
    if len(idx) == 0:
        return idx
    c = cand[idx]
    first = np.full(c.max() + 1, -1)
    uniq, at = np.unique(c, return_index=True)
    first[uniq] = idx[at]  # the first passing hypothesis of each candidate
    far = np.linalg.norm(tgt_a[idx] - tgt_a[first[c]], axis=1) > merge_px
    rival = np.zeros(c.max() + 1, bool)
    rival[c[far]] = True
    return first[(first >= 0) & ~rival]


def _add(
    m: Map, camera: CameraModel, cfg: Config, kfs: tuple, ed: Edgelets, meas: tuple, one_tables: tuple
) -> np.ndarray:
    """Refine the new edgelets on their source, target and check measurements (poses fixed) and add them with those
    measurements (step 5); returns which of them were added. ``kfs``:
    the source and target keyframes and each new edgelet's check keyframe; ``one_tables``: the hypotheses that
    become them, and the job's pending table rows."""
    one, tables = one_tables
    n = len(one)
    if n == 0:
        return np.zeros(0, bool)
    k, t, checks = kfs
    src, tgt, ver = meas
    lines = [(src.a, src.b), (tgt.a[one], tgt.b[one]), (ver.measurement.a[one], ver.measurement.b[one])]
    kf = np.concatenate([np.full(n, k), np.full(n, t), checks])
    local = np.tile(np.arange(n), len(lines))
    obs = EdgeletObservations(kf, local, np.concatenate([a for a, _ in lines]), np.concatenate([b for _, b in lines]))
    ed = refine_edgelets(camera, m.kf_T_cw, ed, obs, cfg.edgelets, cfg.edgelets.refine_iterations)
    good = np.all(np.isfinite(ed.centre), axis=1)
    ids = m.add_edgelets(ed.centre[good], ed.direction[good], ed.normal[good], k)
    found = [(j, ids, a[good], b[good]) for j, (a, b) in zip((k, t), lines)]
    checks = checks[good]
    a3, b3 = lines[2][0][good], lines[2][1][good]
    found += [(c, ids[checks == c], a3[checks == c], b3[checks == c]) for c in np.unique(checks).tolist()]
    record(m, found, tables)
    return good
