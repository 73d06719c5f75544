"""The viewer's default layout: map and state on the left, the camera image and PTAM Fig. 4's plots on the right."""

from __future__ import annotations

import rerun.blueprint as rrb


def default_blueprint() -> rrb.Blueprint:
    left = rrb.Vertical(rrb.Spatial3DView(origin="world", name="map"),
                        rrb.StateTimelineView(origin="state", name="tracking state"), row_shares=[5, 1])
    right = rrb.Vertical(rrb.Spatial2DView(origin="world/camera/image", name="camera"),
                         rrb.TimeSeriesView(origin="plots/tracking", name="tracking time (ms)"),
                         rrb.TimeSeriesView(origin="plots/map", name="map points"),
                         rrb.TimeSeriesView(origin="plots/keyframes", name="keyframes"),
                         rrb.TimeSeriesView(origin="plots/mapper", name="mapper: queue, BA (1 local, 2 global)"),
                         row_shares=[4, 1, 1, 1, 1])
    return rrb.Blueprint(rrb.Horizontal(left, right, column_shares=[3, 2]), collapse_panels=True)
