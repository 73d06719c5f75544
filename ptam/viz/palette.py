"""Colours of the viewer, following PTAM's own display where it has one."""

from __future__ import annotations

import numpy as np

from ..vocabulary import TrackingState as S

# PTAM code (KeyFrame.cc, gavLevelColors): pyramid levels 0-3 drawn red, yellow, green, blue; deeper levels (never
# used with PTAM's four) pale yellow. Used for measurements (by search level) and map points (by source level).
LEVEL_COLOURS = np.array([[255, 0, 0], [255, 255, 0], [0, 255, 0], [0, 0, 178], [255, 255, 178]], np.uint8)

FAILED_COLOUR = (150, 150, 150)  # measurements searched but not found
TRAIL_COLOUR = (255, 160, 0)  # PTAM §6.1 stereo-initialisation trails
TRAJECTORY_COLOUR = (255, 140, 0)
KEYFRAME_COLOUR = (80, 160, 255)
PANORAMA_COLOUR = (230, 80, 230)  # Gauglitz et al. §3.2: panorama keyframes and their rays (no depth)
# Gauglitz et al. §5.3: keyframes that came with merged tracks, by part (1, 2, ...; cycled), beside KEYFRAME_COLOUR.
PART_COLOURS = np.array([[80, 220, 120], [255, 200, 60], [0, 200, 220], [200, 120, 60], [160, 120, 255]], np.uint8)
EDGELET_COLOUR = (0, 230, 255)  # Agility §4: edgelets in the map and found in the frame (failed ones FAILED_COLOUR)
GRID_COLOUR = (128, 128, 128)  # PTAM code MapViewer::DrawGrid: grey lines ...
GRID_AXIS_COLOUR = (255, 255, 255)  # ... the two through the origin white

# Tracking states in the state timeline.
STATE_COLOURS = {
    S.INITIALISING: (120, 120, 255),
    S.GOOD: (0, 200, 0),
    S.POOR: (230, 200, 0),
    S.LOST: (220, 0, 0),
    S.RELOCALISING: (255, 120, 0),
}


def keyframe_colour(kf) -> tuple:
    """A keyframe's frustum: panorama keyframes in their colour, else by the part of the map it came with."""
    if kf.panorama:
        return PANORAMA_COLOUR
    return KEYFRAME_COLOUR if kf.part == 0 else tuple(int(c) for c in PART_COLOURS[(kf.part - 1) % len(PART_COLOURS)])


def level_colours(levels: np.ndarray) -> np.ndarray:
    """(N,) pyramid levels -> (N, 3) uint8 colours."""
    return LEVEL_COLOURS[np.minimum(np.asarray(levels, dtype=np.int64), len(LEVEL_COLOURS) - 1)]
