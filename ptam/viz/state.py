"""The tracking state shown to the user (viewer and status line): initialising, good, poor, lost, relocalising.

Good and poor are PTAM's tracking quality (§5.6) of a tracked frame; lost is a run of bad frames (§5.6), during
which the system tries to relocalise (Agility §7)."""

from __future__ import annotations

INITIALISING, GOOD, POOR, LOST, RELOCALISING = "initialising", "good", "poor", "lost", "relocalising"
STATES = (INITIALISING, GOOD, POOR, LOST, RELOCALISING)


def state_of(outcome) -> str:
    """The state of one :class:`ptam.system.FrameOutcome`."""
    if outcome.state in (INITIALISING, LOST, RELOCALISING):
        return outcome.state
    return GOOD if getattr(outcome.result, "quality", GOOD) == GOOD else POOR
