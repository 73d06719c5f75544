"""One camera frame as delivered to the tracker (PTAM §7: 8bpp greyscale for tracking, colour for display)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, slots=True)
class Frame:
    """``index`` counts from 0 in the source; ``timestamp`` is in seconds; ``image`` is grey uint8 (H, W);
    ``colour`` is the BGR uint8 (H, W, 3) original when the input was colour, else None."""

    index: int
    timestamp: float
    image: np.ndarray
    colour: np.ndarray | None = None
