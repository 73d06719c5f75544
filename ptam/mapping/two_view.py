"""Relative pose and structure from the initialisation trails (PTAM §6.1, Gauglitz §6.1).

Both relations are estimated robustly with OpenCV's USAC: the essential matrix by the five-point algorithm
(PTAM §6.1, DESIGN.md) and a homography (what PTAM's public code uses, because the typical first view is a
planar desk, on which the essential matrix is ill-conditioned). Torr's GRIC picks the better model (as in
Gauglitz §6.1). E is decomposed by cheirality (``recoverPose``); H by OpenCV's analytic decomposition, the
solution kept that puts most matches in front of both cameras and, among near ties, explains all matches
best as an essential matrix [t]ₓR (off-plane points break the planar two-fold ambiguity). Matches consistent
with the chosen epipolar geometry are triangulated. Failures carry a reason that the system logs before it
restarts initialisation: too few trails, too few inliers, or too little parallax (rotation-only motion).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.special import bdtrc

from ..geometry import se3, so3
from ..geometry.triangulation import triangulate_two_view
from .gric import CHI2_MEDIAN, gric, gric_eq12, homography_sampson_sq, sampson_sq

_USAC = {
    "default": cv2.USAC_DEFAULT,
    "magsac": cv2.USAC_MAGSAC,
    "accurate": cv2.USAC_ACCURATE,
    "prosac": cv2.USAC_PROSAC,
    "ransac": cv2.RANSAC,
}


class InitFailure(Exception):
    """Initialisation did not succeed; ``str(e)`` is the reason."""


class AmbiguousPair(InitFailure):
    """The pair fits two relative poses equally; the same first keyframe with a later second one may not."""


@dataclass(frozen=True)
class TwoViewResult:
    T_c1c0: np.ndarray  # (4, 4) second camera from first camera, unit baseline
    X0: np.ndarray  # (K, 3) inlier points in the first camera's frame
    inliers: np.ndarray  # (N,) bool over the input matches
    median_parallax_deg: float
    model: str  # "E" or "H", the GRIC choice


def _triangulate(T: np.ndarray, r0: np.ndarray, r1: np.ndarray):
    X0 = triangulate_two_view(np.eye(4), T, r0, r1)
    X1 = se3.transform(T, X0)
    return X0, X1


@dataclass(frozen=True)
class _Decomposition:
    """One decomposition of H: the relative pose, which of all N matches it puts in front of both cameras (of H's
    inliers; False for the others) and their squared Sampson errors under its E, in σ²."""

    T: np.ndarray
    front: np.ndarray
    e2: np.ndarray

    def cost(self, cap: float) -> float:
        return float(np.minimum(self.e2, cap).sum())


def _decompositions(H: np.ndarray, r0: np.ndarray, r1: np.ndarray, inl: np.ndarray, sigma: float):
    _, Rs, ts, _ = cv2.decomposeHomographyMat(H, np.eye(3))
    out = []
    for R, t in zip(Rs, ts):
        t = t.ravel()
        if np.linalg.norm(t) < 1e-12:
            continue
        T = se3.from_Rt(R, t / np.linalg.norm(t))
        X0, X1 = _triangulate(T, r0[inl], r1[inl])
        front = np.zeros(len(r0), bool)
        front[inl] = (X0[:, 2] > 0) & (X1[:, 2] > 0)
        out.append(_Decomposition(T, front, sampson_sq(so3.hat(T[:3, 3]) @ T[:3, :3], r0, r1) / sigma**2))
    return out


def _from_homography(H: np.ndarray, r0: np.ndarray, r1: np.ndarray, inl: np.ndarray, sigma: float, c):
    """The decomposition of H with most inliers in front of both cameras (PTAM code, HomographyInit::
    ChooseBestDecomposition). Faugeras and Lustman's two-way ambiguity (a second distinct decomposition with
    ``c.homography_ambiguity_ratio`` as many in front) PTAM resolves by the capped Sampson error of all matches
    under each one's E (``c.homography_resolve_ambiguity``). But every point on the plane fits both equally, so that
    is decided by the few off it and by the wrong matches: desk_corner filmed at 10 fps paired two frames with 40
    surviving trails, 36 in front under both, and got a map 9.4° and 50° (translation direction) off; on a plane
    alone, pushed towards a desk, 18 of 40 synthetic pairs came out wrong, at Sampson sums up to 1.26 times the right
    one's. Here the matches that tell the two apart decide (``_evidence``): one is taken only when they favour it
    beyond chance (a sign test at ``c.homography_ambiguity_alpha``), else ``AmbiguousPair``, and the same first
    keyframe with a later second one is tried."""
    ds = _decompositions(H, r0, r1, inl, sigma)
    if not ds:
        return None
    best_front = max(int(d.front.sum()) for d in ds)
    cap = c.gric_lambda3 * 2.0
    near = sorted(
        (d for d in ds if d.front.sum() >= c.homography_ambiguity_ratio * best_front), key=lambda d: d.cost(cap)
    )
    rivals = [d for d in near[1:] if _distinct(near[0].T, d.T, c.min_parallax_deg)]
    if not rivals or c.homography_resolve_ambiguity:
        return near[0].T
    a, b = near[0], rivals[0]
    ka, kb = _evidence(a, b, c.inlier_sigmas), _evidence(b, a, c.inlier_sigmas)
    if _sign_test(max(ka, kb), min(ka, kb)) > c.homography_ambiguity_alpha:
        raise AmbiguousPair(
            f"the homography's two decompositions fit equally ({int(a.front.sum())} and {int(b.front.sum())} points "
            f"in front of both cameras, {ka} and {kb} matches for one against the other): waiting for a pair that "
            "tells them apart (points off the plane, or a move across it)"
        )
    return a.T if ka >= kb else b.T


def _evidence(a: _Decomposition, b: _Decomposition, inlier_sigmas: float) -> int:
    """Matches that favour decomposition a over b and not b over a: in front of both cameras under a only, or
    within the inlier band (``inlier_sigmas`` σ) of a's E only. A point on the plane fits both and counts for
    neither."""
    t2 = inlier_sigmas**2
    for_a = (a.front & ~b.front) | ((a.e2 < t2) & (b.e2 >= t2))
    for_b = (b.front & ~a.front) | ((b.e2 < t2) & (a.e2 >= t2))
    return int((for_a & ~for_b).sum())


def _sign_test(k: int, m: int) -> float:
    """One-sided sign test: the chance of k or more of k + m matches favouring one side when each favours either
    with probability ½ (no information): the binomial tail P(X ≥ k) = ``bdtrc(k − 1, n, ½)``."""
    return float(bdtrc(k - 1, k + m, 0.5)) if k > 0 else 1.0


def _distinct(A: np.ndarray, B: np.ndarray, tol_deg: float) -> bool:
    """Two relative poses (unit translations) differ by more than ``tol_deg`` in rotation or translation direction:
    where the plane's normal is along the translation the two decompositions coincide, and that is no ambiguity."""
    turn = float(np.degrees(np.linalg.norm(so3.log(A[:3, :3] @ B[:3, :3].T))))
    move = float(np.degrees(np.arccos(np.clip(A[:3, 3] @ B[:3, 3], -1.0, 1.0))))
    return max(turn, move) > tol_deg


def estimate_two_view(camera, xy0: np.ndarray, xy1: np.ndarray, init_cfg) -> TwoViewResult:
    """Matches in level-0 pixels (N, 2) -> relative pose and triangulated inliers."""
    c = init_cfg
    n = len(xy0)
    if n < c.min_matches:
        raise InitFailure(f"too few trails ({n} < {c.min_matches})")
    xy0 = np.asarray(xy0, np.float64)
    xy1 = np.asarray(xy1, np.float64)
    r0 = camera.unproject(xy0)
    r1 = camera.unproject(xy1)
    f = 0.5 * (camera.fx + camera.fy)
    sigma = c.essential_threshold_px / f
    model, E, mask_e, H, mask_h = select_model(r0, r1, sigma, c, f)
    if model == "E":
        _, R, t, _ = cv2.recoverPose(E, r0, r1, np.eye(3), mask=mask_e.astype(np.uint8).copy())
        T = se3.from_Rt(R, t.ravel())
    else:
        T = _from_homography(H, r0, r1, mask_h.ravel().astype(bool), sigma, c)
        if T is None:
            raise InitFailure("the homography has no usable decomposition (no translation)")
    # Inliers of the chosen epipolar geometry, then triangulation with cheirality and pixel checks.
    Eb = so3.hat(T[:3, 3]) @ T[:3, :3]
    inl = sampson_sq(Eb, r0, r1) < (c.inlier_sigmas * sigma) ** 2
    if inl.sum() < c.min_inliers:
        raise InitFailure(f"too few inliers ({int(inl.sum())} < {c.min_inliers}, model {model})")
    X0, X1 = _triangulate(T, r0[inl], r1[inl])
    e0 = np.linalg.norm(camera.project(X0) - xy0[inl], axis=1)
    e1 = np.linalg.norm(camera.project(X1) - xy1[inl], axis=1)
    good = (X0[:, 2] > 0) & (X1[:, 2] > 0) & (e0 < c.triangulation_max_error_px) & (e1 < c.triangulation_max_error_px)
    idx = np.flatnonzero(inl)
    inl = np.zeros(n, bool)
    inl[idx[good]] = True
    X0 = X0[good]
    if len(X0) < c.min_inliers:
        raise InitFailure(f"too few triangulated inliers ({len(X0)} < {c.min_inliers}, model {model})")
    c1 = -T[:3, :3].T @ T[:3, 3]
    a = X0 / np.linalg.norm(X0, axis=1, keepdims=True)
    b = X0 - c1
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    parallax = float(np.degrees(np.median(np.arccos(np.clip((a * b).sum(axis=1), -1.0, 1.0)))))
    if parallax < c.min_parallax_deg:
        raise InitFailure(
            f"too little parallax (median {parallax:.2f} deg < {c.min_parallax_deg} deg, model "
            f"{model}): the camera rotated more than it translated"
        )
    return TwoViewResult(T, X0, inl, parallax, model)


@dataclass(frozen=True)
class _Fits:
    """E and H fitted to the same matches (None where a fit failed), their inlier masks, and the squared
    first-order errors of every match under each fitted relation, in the order E, H."""

    E: np.ndarray | None
    mask_e: np.ndarray | None
    H: np.ndarray | None
    mask_h: np.ndarray | None
    e2: dict[str, np.ndarray]


def _fit_relations(r0: np.ndarray, r1: np.ndarray, threshold: float, c, method: str) -> _Fits:
    """E (five-point) and H fitted robustly by OpenCV's USAC ``method`` to unit-plane matches, within
    ``threshold`` (unit plane)."""
    usac = _USAC[method]
    cv2.setRNGSeed(c.ransac_seed)  # deterministic runs (sync-mode tests compare trajectories bit for bit)
    E_, mask_e = cv2.findEssentialMat(r0, r1, np.eye(3), method=usac, prob=c.ransac_confidence, threshold=threshold)
    H_, mask_h = cv2.findHomography(r0, r1, usac, threshold, maxIters=10000, confidence=c.ransac_confidence)
    E = np.asarray(E_) if E_ is not None and E_.shape == (3, 3) else None  # several solutions: none kept
    H = np.asarray(H_) if H_ is not None and H_.shape == (3, 3) else None
    e2 = {}
    if E is not None:
        e2["E"] = sampson_sq(E, r0, r1)
    if H is not None:
        e2["H"] = homography_sampson_sq(H, r0, r1)
    return _Fits(E, mask_e, H, mask_h, e2)


def _noise_sigma(e2_essential: np.ndarray, c, f: float) -> float:
    """GRIC needs the noise σ (Torr 1998; Gauglitz §4.2 estimates it by EM): the general model fits planar and
    3-D scenes alike, so the median of its squared errors, over the median of χ²₁, estimates it (never below
    ``init.gric_min_sigma_px``)."""
    return max(float(np.sqrt(np.median(e2_essential) / CHI2_MEDIAN[1])), c.gric_min_sigma_px / f)


def select_model(r0: np.ndarray, r1: np.ndarray, sigma: float, c, f: float) -> tuple:
    """E (five-point) and H fitted robustly to unit-plane matches, the one with the lower GRIC chosen
    (Gauglitz §6.1): (model, E, E's inlier mask, H, H's inlier mask). ``sigma``: the RANSAC threshold (unit
    plane); ``f``: the focal length in pixels."""
    fits = _fit_relations(r0, r1, sigma, c, c.essential_method)
    if "E" in fits.e2 and len(fits.e2["E"]):
        sigma = _noise_sigma(fits.e2["E"], c, f)
    cands = {k: gric(v, sigma, k, c.gric_lambda3) for k, v in fits.e2.items()}
    if not cands:
        raise InitFailure("neither an essential matrix nor a homography fits the trails")
    return min(cands, key=lambda k: cands[k]), fits.E, fits.mask_e, fits.H, fits.mask_h


def rotation_explains(camera, xy0: np.ndarray, xy1: np.ndarray, init_cfg, ms, method: str, t_max_rel: float) -> bool:
    """Model-free check for rotation-only motion (Gauglitz §4.2, §6): whether matches ``xy0`` -> ``xy1`` (level-0
    pixels) are a rotation within the rotation-only model's tolerance. An essential matrix and a homography are
    fitted robustly (OpenCV USAC, ``method``), the best rotation to their inliers (Kabsch), and GRIC picks among
    the three (Table 2: E k = 5, D − d = 1; H k = 8 and [R|0] k = 3, D − d = 2). A translating model still counts as
    a rotation while the translation stays within ``t_max_rel``, the [R|t ≤ t_max] model's t_max / depth (§6.2): for
    H, its translation over the plane's distance (the smallest of its decompositions: on a planar desk a sideways
    move looks like a pan to first order, so a rotation's residuals would hide it); for E, the
    translation over the median depth of the matches it triangulates. Each model's σ and inlier ratio come from
    EM, its score from eq. (12) (``ms``: the model-selection config)."""
    c = init_cfg
    if len(xy0) < c.min_matches:
        return True  # too few matches to tell: the tracker's own quality decides
    r0 = camera.unproject(np.asarray(xy0, np.float64))
    r1 = camera.unproject(np.asarray(xy1, np.float64))
    f = 0.5 * (camera.fx + camera.fy)
    fits = _fit_relations(r0, r1, c.essential_threshold_px / f, c, method)
    if not fits.e2:
        return True
    masks = [
        np.asarray(m).ravel().astype(bool) for m, M in ((fits.mask_e, fits.E), (fits.mask_h, fits.H)) if M is not None
    ]
    inl = np.logical_or.reduce(masks)
    e2 = {"R": homography_sampson_sq(_best_rotation(r0[inl], r1[inl]), r0, r1), **fits.e2}
    # Eq. (12): the disparity range Δ that E expects is the one at which the rotation-only model gives way (t_max
    # seen from its depth: α_max·f), and S the search region around a predicted feature (§6.1–§6.2).
    delta = t_max_rel * f
    score = {k: gric_eq12(v * f * f, k, delta, 2.0 * delta, ms) for k, v in e2.items()}
    best = min(score, key=lambda k: score[k])
    if best == "H":
        assert fits.H is not None
        _, _, ts, _ = cv2.decomposeHomographyMat(fits.H, np.eye(3))
        return min(float(np.linalg.norm(t)) for t in ts) <= t_max_rel
    if best == "E":
        assert fits.E is not None and fits.mask_e is not None
        inl = fits.mask_e.ravel().astype(bool)
        _, R_e, t, _ = cv2.recoverPose(fits.E, r0, r1, np.eye(3), mask=fits.mask_e.astype(np.uint8).copy())
        X0, _ = _triangulate(se3.from_Rt(R_e, t.ravel()), r0[inl], r1[inl])  # depths in units of the translation
        depth = X0[:, 2][X0[:, 2] > 0]
        return len(depth) == 0 or 1.0 / float(np.median(depth)) <= t_max_rel
    return True


def _best_rotation(r0: np.ndarray, r1: np.ndarray) -> np.ndarray:
    """The rotation R with bearing(r1) ≈ R·bearing(r0) in least squares (Kabsch), unit-plane points."""
    a = np.concatenate([r0, np.ones((len(r0), 1))], axis=1)
    b = np.concatenate([r1, np.ones((len(r1), 1))], axis=1)
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    U, _, Vt = np.linalg.svd(b.T @ a)
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
