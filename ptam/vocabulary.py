"""The project's closed vocabularies, each defined once: argparse choices, config validation, the system, the
viewer and the AR layer all use these enums (their values are the strings users type and files store)."""

from __future__ import annotations

from enum import StrEnum

import yaml


class TrackingState(StrEnum):
    """What the user is told about a frame (viewer, status line). Good and poor are PTAM's tracking quality of a
    tracked frame (§5.6); lost is a run of bad frames (§5.6), during which relocalisation runs (Agility §7)."""

    INITIALISING = "initialising"
    GOOD = "good"
    POOR = "poor"
    LOST = "lost"
    RELOCALISING = "relocalising"

    @property
    def is_tracking(self) -> bool:
        """A pose was estimated for the frame (good or poor quality)."""
        return self in (TrackingState.GOOD, TrackingState.POOR)


class Quality(StrEnum):
    """PTAM §5.6 tracking quality of one frame, from the fraction of successful observations."""

    GOOD = "good"
    POOR = "poor"
    BAD = "bad"


class RunMode(StrEnum):
    """How tracker and mapper share time (DESIGN: Concurrency)."""

    SYNC = "sync"
    ASYNC = "async"
    REALTIME = "realtime"


class ArScene(StrEnum):
    """The AR content drawn on the dominant plane (PTAM §7.5)."""

    EYES = "eyes"
    GAME = "game"
    GRID = "grid"
    OFF = "off"


class RrdFooter(StrEnum):
    """Whether an ``.rrd`` recording ends with rerun's footer (a manifest of every chunk, for random access). The
    sink keeps that manifest in memory until the file is closed, a few KB per chunk: 12–16 MB a minute of ptam's
    viewer logging at 30 Hz, without bound on a live camera. ``auto``: a footer for videos and datasets, none live."""

    AUTO = "auto"
    ALWAYS = "always"
    NEVER = "never"


class InitMode(StrEnum):
    """How the two stereo keyframes are chosen (PTAM §6.1): key presses (live) or from the trails (files)."""

    AUTO = "auto"
    KEY = "key"


class SearchLevelRule(StrEnum):
    """Pyramid level for a warped patch search (PTAM §5.3 vs PTAM code)."""

    CLOSEST = "closest"
    PTAM_CODE = "ptam_code"


class EssentialMethod(StrEnum):
    """Robust estimator for the five-point essential matrix (OpenCV USAC flavours)."""

    DEFAULT = "default"
    MAGSAC = "magsac"
    ACCURATE = "accurate"
    PROSAC = "prosac"
    RANSAC = "ransac"


class ChessboardDetector(StrEnum):
    SB = "sb"
    CLASSIC = "classic"


class CalibrationLoss(StrEnum):
    """scipy.optimize.least_squares loss for the calibration fit."""

    LINEAR = "linear"
    HUBER = "huber"
    SOFT_L1 = "soft_l1"
    CAUCHY = "cauchy"


class LensModel(StrEnum):
    """Camera models: PTAM's FOV (ATAN) model, the plain pinhole, OpenCV's radial-tangential."""

    PINHOLE = "pinhole"
    FOV = "fov"
    RADTAN = "radtan"


class PoseModel(StrEnum):
    """The model chosen for a frame's motion (Gauglitz et al. §4.2, §6.2): a general pose against the 3-D map,
    or a rotation about the previous keyframe's centre (a panorama, no new depth)."""

    GENERAL = "R|t"
    ROTATION = "R|0"


class GroupKind(StrEnum):
    """Keyframe groups (Gauglitz et al. §3.2): linked by 3-D poses, or by rotations about one centre."""

    SFM = "sfm"
    PANORAMA = "panorama"


class DistortionModel(StrEnum):
    """Lens models a synthetic calibration sequence can be rendered with."""

    FOV = "fov"
    RADTAN = "radtan"


def choices(enum: type[StrEnum]) -> list[str]:
    """The values of ``enum`` in definition order, for argparse ``choices``."""
    return [m.value for m in enum]


# Files store the plain value, so a config or scene written from an enum reads back anywhere.
yaml.SafeDumper.add_multi_representer(StrEnum, lambda dumper, value: dumper.represent_str(str(value)))
