"""``ptam bench agility``: the cost of the small-blurry-image rotation estimator (Agility §9.2: 0.5 ms per
frame) and of one keyframe relocalisation attempt with a map of 250 keyframes (Agility §7, Fig. 4's map size;
issue 7's target 1 ms for the comparison + 0.5 ms for the alignment).

The rotation estimator runs over every frame of the scene (small image, blur, ESM, SE(2) → 3-D rotation). For
relocalisation, 250 keyframes are spread evenly over the scene with their true poses, their descriptors made
once as keyframes are (not timed), and every other frame is relocalised against them. Pyramids are built
beforehand; numba compilation is excluded by a warm-up call. Wall-clock times on this machine. Then the edgelet
candidates (Agility §4.3: Canny, linking, sub-pixel measurement) are extracted from each keyframe's image, the
step the mapper runs once per keyframe before its epipolar search (issue target: 20 ms). Last, Fig. 5's
points and edgelets found against image motion (``agility_features``, on desk_blur and the edge-rich bricks_blur),
and on the same scenes and desk_bricks the tracker's time per frame with edgelets and with points alone
(``agility_tracking_cost``, §9.2: 12 -> 18 ms).
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from ..edgelet import extract_candidates
from ..errors import InputError
from ..geometry import se3
from ..image.pyramid import Pyramid
from ..image.sbi import SmallBlurryImage
from ..map.keyframe import KeyFrame
from ..map.map import Map
from ..synthetic import ensure_sequence, load_scene
from ..tracking.relocaliser import Relocaliser
from ..tracking.rotation_estimator import RotationEstimator
from .agility_features import FIG5_SCENES, print_features_by_motion, run_features_by_motion
from .agility_tracking_cost import EXTRA_SCENES, print_tracking_cost, tracking_cost

TARGET_MS = {"rotation": 0.5, "compare": 1.0, "align": 0.5, "reloc": 1.5, "edgelets": 20.0}
ROW_NAMES = {
    "rotation": "Rotation estimate per frame",
    "compare": "Reloc: compare with {k} keyframes",
    "align": "Reloc: alignment + rotation",
    "reloc": "Relocalisation total",
    "edgelets": "Edgelet candidates per keyframe",
}


def _pyramid(seq, i: int, cfg) -> Pyramid:
    path = seq / f"rgb/{i:06d}.png"
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise InputError(f"cannot read {path}")
    return Pyramid.build(img, cfg.image)


def _edgelet_extraction_ms(pyramids: list[Pyramid], kf_frames: np.ndarray, cfg) -> np.ndarray:
    """Agility §4.3's candidate extraction (Canny, linking, measurement) on each keyframe's full-size image; the
    first call loads the kernels and is not timed."""
    images = [pyramids[i].levels[0] for i in kf_frames]
    extract_candidates(images[0], cfg.edgelets)
    return np.array([_ms(extract_candidates, img, cfg.edgelets)[0] for img in images])


def _ms(f, *args):
    t = time.perf_counter()
    out = f(*args)
    return 1e3 * (time.perf_counter() - t), out


def run_agility_benchmark(cfg, scene: str = "two_wall", out=print, keyframes: int = 250) -> dict:
    """Time the rotation estimator and relocalisation; print the table and the summary line; return the numbers."""
    sc = load_scene(scene)
    if sc.n_frames < keyframes + 1:
        raise InputError(
            f"bench agility: scene {scene} has {sc.n_frames} frames, fewer than {keyframes} keyframes"
            " and a frame to relocalise"
        )
    seq = ensure_sequence(scene, cfg.synthetic)
    out(f"building pyramids of {scene} ({sc.n_frames} frames) ...")
    pyramids = [_pyramid(seq, i, cfg) for i in range(sc.n_frames)]

    est = RotationEstimator(sc.camera, cfg.rotation)
    est.estimate(pyramids[0])
    est.estimate(pyramids[1])  # compiles the ESM kernel
    est.reset()
    rotation = [_ms(est.estimate, p)[0] for p in pyramids[1:]]

    kf_frames = np.unique(np.linspace(0, sc.n_frames - 1, keyframes).round().astype(int))
    m = Map()
    for k, i in enumerate(kf_frames):
        m.add_keyframe(KeyFrame(k, pyramids[i], 1.0, 0.0, float(sc.timestamps[i])), se3.inv(sc.poses_T_wc[i]))
    snapshot = m.snapshot()
    reloc = Relocaliser(sc.camera, cfg)
    reloc.sync(snapshot)
    queries = np.setdiff1d(np.arange(sc.n_frames), kf_frames)
    reloc.attempt(pyramids[queries[0]], snapshot)  # warm-up
    compare, total, nearest = [], [], []
    centres = sc.poses_T_wc[kf_frames][:, :3, 3]
    for i in queries:
        t, frame = _ms(SmallBlurryImage.from_pyramid, pyramids[i], cfg.reloc.blur_sigma)
        dt, _ = _ms(reloc.descriptor_ssd, frame)
        compare.append(t + dt)
        dt, r = _ms(reloc.attempt, pyramids[i], snapshot)
        total.append(dt)
        gap = np.linalg.norm(centres - sc.poses_T_wc[i][:3, 3], axis=1)
        nearest.append(r.keyframe in np.argsort(gap)[:2])
    rows = {"rotation": np.array(rotation), "compare": np.array(compare), "reloc": np.array(total)}
    rows["align"] = np.maximum(rows["reloc"] - rows["compare"], 0.0)
    rows["edgelets"] = _edgelet_extraction_ms(pyramids, kf_frames, cfg)
    n = len(kf_frames)
    out(
        f"Agility timings: rotation estimator over {len(rotation)} frames of {scene}; relocalisation of "
        f"{len(queries)} frames against {n} keyframes ({100 * np.mean(nearest):.0f}% chose one of the two nearest)"
    )
    out(f"{'':<36}{'target (ms)':>12}{'median (ms)':>13}{'p95 (ms)':>10}")
    for key in ("rotation", "compare", "align", "reloc", "edgelets"):
        v = rows[key]
        out(
            f"{ROW_NAMES[key].format(k=n):<36}{TARGET_MS[key]:>12.1f}{np.median(v):>13.3f}{np.percentile(v, 95):>10.3f}"
        )
    result: dict = {
        "rotation_ms": float(np.median(rows["rotation"])),
        "reloc_ms_250kf": float(np.median(rows["reloc"])),
    }
    out(f"rotation_ms={result['rotation_ms']:.4f} reloc_ms_250kf={result['reloc_ms_250kf']:.4f}")
    result.update(keyframes=n, nearest_fraction=float(np.mean(nearest)))
    result["stage_ms_median"] = {k: float(np.median(v)) for k, v in rows.items()}
    result["features_by_motion"], result["tracking_ms"] = _fig5_and_tracking_cost(cfg, out)
    return result


def _fig5_and_tracking_cost(cfg, out) -> tuple[dict, dict]:
    """Fig. 5's rows per scene, printed, and the tracker's cost of edgelets on the same runs (printed after)."""
    fig5, costs = {}, {}
    for name in FIG5_SCENES:
        seq = ensure_sequence(name, cfg.synthetic)
        rows, system = run_features_by_motion(seq, cfg)
        print_features_by_motion(rows, name, out)
        fig5[name] = rows
        costs[name] = tracking_cost(seq, cfg, system)
    for name in EXTRA_SCENES:
        costs[name] = tracking_cost(ensure_sequence(name, cfg.synthetic), cfg)
    print_tracking_cost(costs, out)
    return fig5, costs
