"""Config section of new tracks on loss and background track merging (Gauglitz et al. TVCG 2013 §4.4, §5.3;
project issue #18)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from .interval import Range


@dataclass(frozen=True)
class TracksConfig:
    new_on_loss: bool
    merge: bool
    merge_min_common: Annotated[int, Range("[1, inf)")]
    merge_common_radius_px: Annotated[float, Range("(0, inf)")]
    merge_max_scale_spread: Annotated[float, Range("(0, inf)")]
    merge_agreement_sigmas: Annotated[float, Range("(0, inf)")]
