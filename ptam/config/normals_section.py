"""Config section of feature-normal estimation (Gauglitz et al. TVCG 2013 §5.4, project issue #18)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from .interval import Range


@dataclass(frozen=True)
class NormalsConfig:
    enabled: bool
    batch_points: Annotated[int, Range("[1, inf)")]
    patch_size: Annotated[int, Range("[3, inf)")]
    max_iterations: Annotated[int, Range("[1, inf)")]
    converge_px: Annotated[float, Range("(0, inf)")]
    min_ncc: Annotated[float, Range("[-1, 1]")]
    min_parallax_deg: Annotated[float, Range("[0, 180)")]
    estimates_per_point: Annotated[int, Range("[1, inf)")]
    min_estimates: Annotated[int, Range("[1, inf)")]
    seed: Annotated[int, Range("[0, inf)")]
