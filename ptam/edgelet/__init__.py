"""Edgelets: edge features for agile tracking (Agility §4–§5, project issue #17).

An edgelet is a short, locally straight piece of an intensity edge, stored as a 3-D frame (``edgelet``):
projected into views (``edgelet_projection``), measured in keyframes by five perpendicular searches and a line
fit (``edgelet_measure``), proposed from Canny edges (``edgelet_candidates``), triangulated from two keyframes
and checked in a third (``edgelet_triangulation``), adjusted by bundle adjustment through two perpendicular
distances per measurement (``edgelet_ba``), and tracked at frame rate by a blur-matched sawtooth search with a
per-keyframe visibility table (``sawtooth``).
"""

from .edgelet import EDGELET_DOF, Edgelets, perp
from .edgelet_ba import EdgeletObservations, EdgeletTerms, edgelet_terms, refine_edgelets, sample_along
from .edgelet_candidates import EdgeletCandidates, extract_candidates, gradient_at, maximal_edgels, smoothed
from .edgelet_measure import LineMeasurements, measure_in_keyframe
from .edgelet_projection import (
    ImageEdgelets,
    blur_lengths,
    project_edgelets,
    project_edgelets_with_jacobian,
)
from .edgelet_triangulation import (
    Triangulation,
    Verification,
    line_planes,
    line_rays,
    triangulate_edgelets,
    verify_edgelets,
)
from .sawtooth import SawtoothResult, VisibilityTable, build_visibility_table, search_edgelets, table_blurs

__all__ = [
    "EDGELET_DOF",
    "EdgeletCandidates",
    "EdgeletObservations",
    "EdgeletTerms",
    "Edgelets",
    "ImageEdgelets",
    "LineMeasurements",
    "SawtoothResult",
    "Triangulation",
    "Verification",
    "VisibilityTable",
    "blur_lengths",
    "build_visibility_table",
    "edgelet_terms",
    "extract_candidates",
    "gradient_at",
    "line_planes",
    "line_rays",
    "maximal_edgels",
    "measure_in_keyframe",
    "perp",
    "project_edgelets",
    "project_edgelets_with_jacobian",
    "refine_edgelets",
    "sample_along",
    "smoothed",
    "search_edgelets",
    "table_blurs",
    "triangulate_edgelets",
    "verify_edgelets",
]
