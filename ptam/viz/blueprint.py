"""The viewer's default layout: map and state on the left, the camera image and PTAM Fig. 4's plots on the right.

With the AR view on, the augmented camera image takes the biggest panel (PTAM §7.5: it is what the user looks
at), with the raw image and its measurements in the tab beside it; the map moves to the top right.
"""

from __future__ import annotations

import rerun.blueprint as rrb

CAMERA_IMAGE = "world/camera/image"
AUGMENTED_IMAGE = "camera/augmented"


def _plots() -> list:
    return [
        rrb.TimeSeriesView(origin="plots/tracking", name="tracking time (ms)"),
        rrb.TimeSeriesView(origin="plots/map", name="map points"),
        rrb.TimeSeriesView(origin="plots/keyframes", name="keyframes"),
        rrb.TimeSeriesView(origin="plots/mapper", name="mapper: queue, BA (1 local, 2 global)"),
    ]


def default_blueprint(augmented: bool = False) -> rrb.Blueprint:
    map_view = rrb.Spatial3DView(origin="world", name="map")
    camera = rrb.Spatial2DView(origin=CAMERA_IMAGE, name="camera")
    state = rrb.Tabs(
        rrb.StateTimelineView(origin="state", name="tracking state"),
        rrb.TextLogView(origin="events", name="tracks"),  # switches and merges (Gauglitz et al. §4.4, §5.3)
    )
    if augmented:
        ar = rrb.Spatial2DView(origin=AUGMENTED_IMAGE, name="augmented (AR)")
        left = rrb.Vertical(rrb.Tabs(ar, camera, active_tab=0), state, row_shares=[5, 1])
        right = rrb.Vertical(map_view, *_plots(), row_shares=[4, 1, 1, 1, 1])
    else:
        left = rrb.Vertical(map_view, state, row_shares=[5, 1])
        right = rrb.Vertical(camera, *_plots(), row_shares=[4, 1, 1, 1, 1])
    return rrb.Blueprint(rrb.Horizontal(left, right, column_shares=[3, 2]), collapse_panels=True)
