"""Colours of the AR overlay (BGR, 0–255): appearance only, no algorithm depends on them."""

EYE_WHITE = (0.85 * 255, 0.90 * 255, 0.92 * 255)  # PTAM code EyeGame::DrawEye: glColor(0.92, 0.9, 0.85)
EYE_IRIS = (255.0, 0.0, 0.0)  # PTAM code: blue
EYE_PUPIL = (0.0, 0.0, 0.0)  # PTAM code: black
SHADOW = (0.0, 0.0, 0.0)
GRID = (255, 255, 255)  # PTAM code DrawFadingGrid: white
TARGETS = (
    (40.0, 40.0, 230.0),
    (30.0, 160.0, 250.0),
    (60.0, 200.0, 60.0),
    (230.0, 120.0, 40.0),
    (200.0, 60.0, 200.0),
)  # beach-ball stripes, one colour per target (cycled)
TARGET_STRIPE = (245.0, 245.0, 245.0)
TARGET_CAP = (30.0, 220.0, 250.0)
AIM_RING = (60.0, 255.0, 60.0)
AIM_RING_LOCKED = (40.0, 40.0, 255.0)
BURST = (40.0, 220.0, 255.0)
CROSSHAIR = (60, 255, 60)
HUD_TEXT = (255, 255, 255)
TARGET_SPECULAR = 0.6  # beach balls are less glossy than eyes
CROSSHAIR_ARM_PX = (6, 16)  # screen cross-hair arms from 6 to 16 px off the principal point
DWELL_ARC_PX = 20  # radius of the dwell-progress arc
FONT_SCALE = 0.6
TEXT_MARGIN_PX = 10  # the HUD text's distance from the image corner
BOX_MARGIN_PX = 2  # pixel boxes of projected objects are padded by this much
SILHOUETTE_SAMPLES = 32  # outline samples that bound an object's pixel box
AIM_RING_INNER = 0.6  # the aim ring's inner radius as a fraction of ar.crosshair_radius
AIM_RING_ALPHA = 0.9
BURST_GROWTH = 4.0  # a hit's ring grows from one to this many target radii ...
BURST_WIDTH = 0.35  # ... with this width (in target radii) while it fades out
BALL_SECTORS = 6  # beach-ball stripes around the ball ...
BALL_CAP_DEG = 25.0  # ... and its two caps
