"""When the outliers of a bundle adjustment stopped at the iteration limit are acted on (PTAM §6.4).

PTAM's code acts on every adjustment's outliers. A BA stopped at the limit after accepted steps has not reached a
minimum: as a keyframe handed over at a wrong pose (PTAM §9) moves back, the measurements moving it are the ones
it flags, and removing them locks the keyframe where it is (``mapper.unfinished_ba_outliers: false`` leaves
them). Left for ever they are not provisional but ignored: on a map that no step fixes, every run then stops at the
limit with the same outliers, and a mapper with nothing else to do repeats that run without end. So they wait only
while the adjustment is getting somewhere — each stopped run of the same kind (local or global) in a row flagging
fewer measurements than the one before — and are acted on once a run flags as many as the last.
"""

from __future__ import annotations

from .bundle import BundleResult


class UnfinishedOutliers:
    """Per kind of adjustment, the flagged count of the last stopped run whose outliers were left."""

    def __init__(self, act_always: bool) -> None:
        self.act_always = act_always
        self._left: dict[bool, int] = {}

    def final(self, res: BundleResult, recent: bool) -> bool:
        """Whether ``res``'s outliers are acted on now (``recent``: a local adjustment)."""
        unfinished = res.hit_max_iterations and not res.converged and res.accepted > 0
        flagged = len(res.outliers) + len(res.edgelet_outliers)
        last = self._left.pop(recent, None)
        if not unfinished or self.act_always or (last is not None and flagged >= last):
            return True
        self._left[recent] = flagged
        return False
