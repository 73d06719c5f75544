"""The rerun viewer as an observer of :class:`ptam.system.System` (DESIGN.md: observers never block tracking).

Called after every frame in the tracker's thread, :class:`Viewer` only collects references to immutable data (the
frame outcome, the current :class:`MapSnapshot`, the trajectory list and its length, mapper counters) and hands
them to its own logging thread through a bounded queue; when the queue is full the frame is not logged (counted
in ``dropped``). The logging thread does all encoding and rerun calls. Map points and keyframe frusta are logged
only when the mapper has published a new snapshot; keyframe thumbnails once per keyframe.

What is logged (entity paths):

* ``world/camera`` current pose; ``world/camera/image`` the frame, with ``found`` measurements coloured by pyramid
  level (PTAM's colours), ``failed`` ones as small grey dots, the edgelets the tracker found (``edgelets_found``, at
  the found edge) and did not find (``edgelets_failed``, grey, where predicted) as short segments (Agility §5), and
  the stereo-initialisation ``trails`` (PTAM §6.1);
* ``camera/augmented`` the AR worker's augmented frame (PTAM §7.5: what the user looks at), as rendered through the
  lens model, at the same ``frame`` / ``time`` as its camera image: ``Viewer.augmented`` is the AR layer's view
  (:mod:`ptam.viz.augmented`); it runs in the AR worker's thread, asks for at most ``viewer.ar_max_fps`` frames a
  second, encodes them there and only enqueues (skipped, counted in ``ar_dropped``, when full);
* ``world/points`` the good map points coloured by source level; ``world/edgelets`` the good edgelets as 3-D
  segments (Agility §4.1); ``world/panorama_rays`` the panorama features
  (rays without depth, Gauglitz et al. §3.2) at their keyframe's mean depth; ``world/keyframes/NNNN`` one frustum
  per keyframe with its thumbnail, panorama keyframes in the panorama colour; ``world/trajectory/NNNNN`` the
  tracked camera path, logged incrementally in
  strips (at :meth:`Viewer.close`, ``world/trajectory`` holds the whole path as one strip); ``world/grid`` the
  dominant plane z = 0 once a map exists (PTAM §6.1);
* ``state`` initialising / good / poor / lost / relocalising (PTAM §5.6);
* ``plots/...`` tracking ms per frame, map points and keyframes over time (PTAM Fig. 4), the mapper's queue
  length and bundle adjustment activity, and the motion model chosen per frame (``model/rotation_only``).
"""

from __future__ import annotations

import queue
import threading
import time
from dataclasses import dataclass

import cv2
import numpy as np
import rerun as rr

from ..geometry import se3
from ..map.snapshot import MapSnapshot
from ..system.priority import lower_priority
from ..system.run_stats import Latency, RunStats
from ..tracking.edgelet_tracking import EdgeletFrame
from ..vocabulary import PoseModel, TrackingState
from . import map_entities, palette
from .augmented import ArFrame, AugmentedView
from .blueprint import AUGMENTED_IMAGE, default_blueprint

_BA_CODES = {None: 0, "local": 1, "global": 2}
# Vertices per trajectory strip entity: a frame re-logs at most about this many (display only, not a tunable).
_STRIP_VERTICES = 100


def _strip_of(n_vertices: int, k: int) -> int:
    """The strip holding the newest vertex of a path of ``n_vertices`` (≥ 1): strip c spans vertices
    c·k … (c+1)·k, so consecutive strips share one vertex and the path stays connected."""
    return max(n_vertices - 2, 0) // k


def _strip_path(c: int) -> str:
    return f"world/trajectory/{c:05d}"


@dataclass(frozen=True)
class _Item:
    """One frame as handed to the logging thread: references only, nothing copied in the tracker's thread."""

    outcome: object  # FrameOutcome, or None for the final state at close
    state: str
    snapshot: MapSnapshot | None
    trajectory: list  # System.trajectory (append-only; replaced by a reset) ...
    n_trajectory: int  # ... and its length at this frame
    trails: tuple | None  # (start_xy, current_xy) while initialising
    mapper_queue: int
    ba_running: str | None
    track: int = 0  # the current track and the merges so far (Gauglitz et al. §4.4, §5.3)
    merged: int = 0


class Viewer:
    """``Viewer(recording, camera, cfg)`` then ``system.observers.append(viewer)``; :meth:`close` at the end logs
    the final map and trajectory and waits for the logging thread. ``augmented=True``: an AR layer will show its
    frames in :attr:`augmented` (its view: ``layer.listeners.append(viewer.augmented)``), and the layout shows
    them first."""

    def __init__(self, recording: rr.RecordingStream, camera, cfg, augmented: bool = False):
        self.rec = recording
        self.camera = camera
        self.cfg = cfg.viewer
        self._edgelet_px = cfg.edgelets.length_px
        self._nice = cfg.system.background_nice
        self.show_augmented = augmented
        self.queue: queue.Queue = queue.Queue(maxsize=self.cfg.queue_size)
        self.dropped = 0
        self._frame_time: tuple[int, float] | None = None  # the latest tracked frame's place on the timelines
        # Time spent in the tracker's thread per frame, bounded like the run's own timings (hours of live use).
        self.observe_ms = Latency(RunStats.window)
        self._snapshot: MapSnapshot | None = None
        self._kf_logged: tuple = ()  # KeyFrame objects whose thumbnails are logged
        self._kf_poses = np.zeros((0, 4, 4))
        self._trajectory: list | None = None
        self._traj_xyz = np.zeros((0, 3))  # camera centres of the logged trajectory (a buffer, first _traj_n rows)
        self._traj_n = 0
        self._state: str | None = None
        self._grid = False
        self._tracks = (0, 0)  # (current track, merges) last logged
        self._error: BaseException | None = None
        self._log_static()
        self._thread = threading.Thread(target=self._run, name="ptam-viewer", daemon=True)
        self.augmented = AugmentedView(self.cfg, self.queue, self._thread.is_alive)
        self._thread.start()

    # -- tracker's thread ------------------------------------------------------------------------------------
    def __call__(self, outcome, system) -> None:
        t0 = time.perf_counter()
        item = self._capture(outcome, system)
        try:
            self.queue.put_nowait(item)
        except queue.Full:
            self.dropped += 1
        self.observe_ms.append(1e3 * (time.perf_counter() - t0))

    def _capture(self, outcome, system) -> _Item:
        initialising = outcome is not None and outcome.state == TrackingState.INITIALISING
        trails = (system.trails.start_xy, system.trails.current_xy) if initialising and system.init_started else None
        return _Item(
            outcome,
            outcome.state if outcome is not None else self._state or TrackingState.INITIALISING,
            system.mapper.snapshot,
            system.trajectory,
            len(system.trajectory),
            trails,
            system.mapper.queue_size(),
            system.mapper.stats.get("ba_running"),
            system.track_id,
            system.stats.tracks_merged,
        )

    @property
    def ar_dropped(self) -> int:
        """Augmented frames not logged: the logging thread had no room for them."""
        return self.augmented.dropped

    def close(self, system=None) -> None:
        """Log ``system``'s final map and trajectory (never dropped), stop the logging thread, flush."""
        if self._thread.is_alive():
            if system is not None:
                self.queue.put(self._capture(None, system))
            self.queue.put(None)
            self._thread.join()
        self.rec.flush()

    # -- logging thread --------------------------------------------------------------------------------------
    def _run(self) -> None:
        lower_priority(self._nice)
        while True:
            item = self.queue.get()
            if item is None:
                return
            try:
                if isinstance(item, ArFrame):
                    self._log_augmented(item)
                else:
                    self._log(item)
            except Exception as e:  # a display problem must never stop tracking; remember the first one
                self._error = self._error or e

    @property
    def error(self) -> BaseException | None:
        """The first exception raised while logging, if any (logging continues after it)."""
        return self._error

    def _log_static(self) -> None:
        rec, c = self.rec, self.cfg
        rec.send_blueprint(default_blueprint(self.show_augmented))
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)  # PTAM §6.1: +z from the plane to the camera
        f, pp, size = map_entities.level_intrinsics(self.camera, 0)
        rec.log(
            "world/camera/image",
            rr.Pinhole(
                focal_length=f, principal_point=pp, resolution=size, image_plane_distance=c.camera_frustum_depth
            ),
            static=True,
        )
        names = list(palette.STATE_COLOURS)
        rec.log(
            "state", rr.StateConfiguration(values=names, colors=[palette.STATE_COLOURS[n] for n in names]), static=True
        )

    def _emit(self, path: str, *archetypes) -> None:
        self.rec.log(path, *archetypes)
        time.sleep(0)  # hand the GIL to the tracker if it waits for it: the logger never holds it for long

    def _set_time(self, index: int, timestamp: float) -> None:
        self.rec.set_time("frame", sequence=int(index))
        self.rec.set_time("time", duration=float(timestamp))

    def _log(self, item: _Item) -> None:
        o = item.outcome
        if o is not None:
            self._frame_time = (o.index, o.timestamp)
        if self._frame_time is not None:  # also after an augmented frame was logged at its own time
            self._set_time(*self._frame_time)
        if item.state != self._state:
            self._emit("state", rr.StateChange(state=item.state))
            self._state = item.state
        if o is not None:
            self._log_frame(o, item)
        if item.snapshot is not self._snapshot:
            self._log_map(item.snapshot)
        self._log_trajectory(item.trajectory, item.n_trajectory, final=o is None)
        self._log_plots(o, item)

    def _log_augmented(self, a: ArFrame) -> None:
        """The augmented frame (encoded by the AR worker) on the camera's timelines."""
        self._set_time(a.index, a.timestamp)
        self._emit(AUGMENTED_IMAGE, a.image)

    def _log_frame(self, o, item: _Item) -> None:
        c = self.cfg
        frame = o.frame
        if frame is not None:
            img = frame.colour if frame.colour is not None else frame.image
            ok, jpeg = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, c.jpeg_quality])
            if ok:
                self._emit("world/camera/image", rr.EncodedImage(contents=jpeg.tobytes(), media_type="image/jpeg"))
        T_cw = o.T_cw if o.T_cw is not None else o.panorama_T_cw  # before the map: the panorama's rotation
        if T_cw is not None:
            T_wc = se3.inv(T_cw)
            self._emit("world/camera", rr.Transform3D(translation=T_wc[:3, 3], mat3x3=T_wc[:3, :3]))
        found_xy, found_level, failed_xy = np.zeros((0, 2)), np.zeros(0, np.int8), np.zeros((0, 2))
        if o.result is not None:
            m = o.result.measurements
            found_xy, found_level = m.xy[m.found], m.level[m.found]
            missed = m.point_ids[~m.found]
            # Before the map the tracker follows a panorama the viewer does not hold: its found rays only.
            if len(missed) and item.snapshot is not None and o.state != TrackingState.INITIALISING:
                Xc = se3.transform(o.result.T_cw, item.snapshot.X[missed])
                failed_xy = self.camera.project(Xc[Xc[:, 2] > 0])
        off = map_entities.RERUN_PIXEL_OFFSET
        self._emit(
            "world/camera/image/found",
            rr.Points2D(found_xy + off, colors=palette.level_colours(found_level), radii=c.measurement_radius_px),
        )
        self._emit(
            "world/camera/image/failed",
            rr.Points2D(failed_xy + off, colors=palette.FAILED_COLOUR, radii=c.failed_radius_px),
        )
        self._log_frame_edgelets(o)
        start, current = (np.zeros((0, 2)), np.zeros((0, 2))) if item.trails is None else item.trails
        self._emit(
            "world/camera/image/trails",
            rr.Arrows2D(
                origins=np.asarray(start, np.float64) + off,
                vectors=np.asarray(current - start, np.float64),
                colors=palette.TRAIL_COLOUR,
            ),
        )

    def _log_frame_edgelets(self, o) -> None:
        """The fine stage's edgelet searches (Agility §5.1), as segments across their search normals."""
        e = o.result.edgelets if o.result is not None and o.result.edgelets is not None else EdgeletFrame.empty()
        for name, sel, colour in (
            ("found", e.found, palette.EDGELET_COLOUR),
            ("failed", ~e.found, palette.FAILED_COLOUR),
        ):
            lines = map_entities.image_segments(e.xy[sel], e.normal[sel], self._edgelet_px)
            self._emit(
                f"world/camera/image/edgelets_{name}",
                rr.LineStrips2D(lines, colors=colour, radii=self.cfg.edgelet_radius_px),
            )

    def _log_map(self, snap: MapSnapshot | None) -> None:
        c = self.cfg
        self._snapshot = snap
        keyframes = snap.keyframes if snap is not None else ()
        if self._kf_logged and (not keyframes or keyframes[0] is not self._kf_logged[0]):
            # A new map (System.reset): forget everything drawn for the old one.
            self._emit("world/keyframes", rr.Clear(recursive=True))
            self._emit("world/grid", rr.Clear(recursive=False))
            self._kf_logged, self._kf_poses, self._grid = (), np.zeros((0, 4, 4)), False
        if snap is None:
            self._emit("world/points", rr.Points3D(np.zeros((0, 3))))
            self._emit("world/edgelets", rr.LineStrips3D(np.zeros((0, 2, 3))))
            return
        self._log_features(snap)
        n_old = len(self._kf_logged)
        T_wc = np.linalg.inv(snap.kf_T_cw)
        moved = np.ones(len(keyframes), bool)
        moved[:n_old] = np.any(self._kf_poses[:n_old] != snap.kf_T_cw[:n_old], axis=(1, 2))
        level = min(c.thumbnail_level, len(keyframes[0].pyramid.levels) - 1) if keyframes else 0
        f, pp, size = map_entities.level_intrinsics(self.camera, level)
        for i in np.flatnonzero(moved):
            path = f"world/keyframes/{i:04d}"
            self._emit(path, rr.Transform3D(translation=T_wc[i, :3, 3], mat3x3=T_wc[i, :3, :3]))
            if i >= n_old:
                self._emit(
                    f"{path}/image",
                    rr.Pinhole(
                        focal_length=f,
                        principal_point=pp,
                        resolution=size,
                        image_plane_distance=c.frustum_depth,
                        color=palette.keyframe_colour(keyframes[i]),
                    ),
                    rr.Image(keyframes[i].pyramid.levels[level]),
                )
        self._kf_logged, self._kf_poses = keyframes, np.array(snap.kf_T_cw)
        if keyframes and not self._grid:
            lines, axis = map_entities.grid_lines(c.grid_spacing, c.grid_half_cells)
            colours = np.where(axis[:, None], palette.GRID_AXIS_COLOUR, palette.GRID_COLOUR).astype(np.uint8)
            self._emit("world/grid", rr.LineStrips3D(lines, colors=colours))
            self._grid = True

    def _log_features(self, snap: MapSnapshot) -> None:
        """The map's good points, edgelets and panorama rays."""
        c = self.cfg
        good = snap.good_point_indices
        rays = good[snap.ray[good]]
        good = good[~snap.ray[good]]
        self._emit(
            "world/points",
            rr.Points3D(
                snap.X[good],
                colors=palette.level_colours(snap.source_level[good]),
                radii=rr.Radius.ui_points(c.point_radius_ui),
            ),
        )
        edgelets = map_entities.edgelet_segments(snap, self.camera, snap.good_edgelet_indices, self._edgelet_px)
        self._emit(
            "world/edgelets",
            rr.LineStrips3D(edgelets, colors=palette.EDGELET_COLOUR, radii=rr.Radius.ui_points(c.edgelet_radius_ui)),
        )
        # Panorama rays have no depth: drawn where they meet the keyframe's mean depth, in the panorama's colour.
        self._emit(
            "world/panorama_rays",
            rr.Points3D(snap.X[rays], colors=palette.PANORAMA_COLOUR, radii=rr.Radius.ui_points(c.point_radius_ui)),
        )

    def _log_trajectory(self, trajectory: list, n: int, final: bool) -> None:
        """The tracked path, incrementally: vertices go into strips of ``_STRIP_VERTICES``, each its own entity
        (``world/trajectory/NNNNN``), and a frame logs only the strips its new vertices touch, so a recording
        grows linearly with the frames. The final item (:meth:`close`) replaces the strips by the whole path as one
        strip at ``world/trajectory``."""
        if trajectory is not self._trajectory:  # the first frame, or a new map after System.reset
            if self._traj_n:
                self._emit("world/trajectory", rr.Clear(recursive=True))
            self._trajectory, self._traj_n = trajectory, 0
        elif n == self._traj_n and not final:
            return
        n_old = self._traj_n
        self._append_vertices(trajectory, n)
        xyz, K = self._traj_xyz[:n], _STRIP_VERTICES
        if final:
            for c in range(_strip_of(n_old, K) + 1 if n_old else 0):
                self._emit(_strip_path(c), rr.Clear(recursive=False))
            self._emit("world/trajectory", rr.LineStrips3D([xyz], colors=palette.TRAJECTORY_COLOUR))
            return
        for c in range(_strip_of(n_old + 1, K), _strip_of(n, K) + 1):
            strip = xyz[c * K : min((c + 1) * K, n - 1) + 1]
            self._emit(_strip_path(c), rr.LineStrips3D([strip], colors=palette.TRAJECTORY_COLOUR))

    def _append_vertices(self, trajectory: list, n: int) -> None:
        """Camera centres of ``trajectory[self._traj_n:n]`` into the vertex buffer (its capacity doubles)."""
        if n > len(self._traj_xyz):
            grown = np.zeros((max(n, 2 * len(self._traj_xyz)), 3))
            grown[: self._traj_n] = self._traj_xyz[: self._traj_n]
            self._traj_xyz = grown
        if n > self._traj_n:
            self._traj_xyz[self._traj_n : n] = [T[:3, 3] for _, T in trajectory[self._traj_n : n]]
        self._traj_n = n

    def _log_plots(self, o, item: _Item) -> None:
        snap = item.snapshot
        if o is not None and o.result is not None:
            self._emit("plots/tracking/tracking_ms", rr.Scalars(o.result.timings.total))
            # Gauglitz et al. §4.2: 1 while the rotation-only model is chosen, 0 for the general pose.
            self._emit("plots/model/rotation_only", rr.Scalars(float(o.result.pose_model == PoseModel.ROTATION)))
        self._emit("plots/map/points", rr.Scalars(snap.n_points if snap is not None else 0))
        self._emit("plots/keyframes/keyframes", rr.Scalars(snap.n_keyframes if snap is not None else 0))
        self._emit("plots/mapper/queue", rr.Scalars(item.mapper_queue))
        self._emit("plots/mapper/bundle_adjustment", rr.Scalars(_BA_CODES.get(item.ba_running, 0)))
        if (item.track, item.merged) != self._tracks:  # the map shown is another track's, or grew by a merge
            what = "merged into" if item.merged > self._tracks[1] else "now"
            self._emit("events", rr.TextLog(f"{what} track {item.track} ({item.merged} merges so far)"))
            self._tracks = (item.track, item.merged)
