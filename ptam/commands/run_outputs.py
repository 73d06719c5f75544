"""The files ``ptam run`` writes (``--trajectory``, ``--keyframes``, ``--map``), kept on disk as the run goes so
that a bad end (SIGKILL, the OOM killer, a native crash, a power cut) loses at most the last second.

- Paths are checked before the first frame (:func:`check_output_paths`): a directory, a missing or read-only
  folder ends the run at once with one line naming the option.
- The trajectory is streamed (:class:`TrajectoryStream`), in time order. In the tracker's thread the observer
  hands the entries appended to ``System.trajectory`` since the last frame to a deque: no I/O, no lock. A flusher
  thread formats them as TUM lines and writes each batch with one ``write``, then fsyncs, every
  ``system.output_flush_s``. The System does not only append: once the map exists it inserts the poses of frames
  seen during initialisation (posed late, in a worker), and a reset replaces the list. The observer notices any
  change other than an in-order append (the entry it saw last is no longer where it was, or a new entry is older
  than its predecessor) and hands over a copy of the whole list instead, once; the flusher then rewrites the file
  atomically, sorted, and appends to it again. So the file on disk is always sorted and complete up to the last
  flush, except that poses inserted late appear only at the flush after their insertion.
- Keyframe poses change under bundle adjustment, so the keyframes file and the map are never appended to: a
  checkpoint thread rewrites both atomically once the map has grown by ``system.map_checkpoint_keyframes``
  keyframes since the last checkpoint, from ``mapper.snapshot`` (immutable, so no copy and no lock).
- Every whole-file write is atomic (:func:`atomic_write`): a temporary file in the same directory, written,
  flushed, fsynced, renamed over the target, then the directory fsynced; a kill at any instant leaves the
  previous complete file (and perhaps a stray ``.NAME.*.tmp``).
- At the end (:meth:`RunOutputs.close`) each output is finished on its own: one that fails does not stop the
  others, and its one-line reason is returned for the command to report after the summary.
"""

from __future__ import annotations

import collections
import logging
import os
import sys
import tempfile
import threading

import numpy as np

from ..errors import InputError, PtamError
from ..eval import write_tum
from ..geometry import so3
from ..map.map_file import save_map

log = logging.getLogger("ptam")

TRAJECTORY_HEADER = "ptam trajectory: timestamp tx ty tz qx qy qz qw (camera-to-world)"
KEYFRAMES_HEADER = "ptam keyframes: timestamp tx ty tz qx qy qz qw (camera-to-world)"
_COLUMNS = "# timestamp tx ty tz qx qy qz qw (camera-to-world)\n"  # as write_tum's last header line
_FILE_MODE = 0o644


# -- paths -------------------------------------------------------------------------------------------------
def output_options(args) -> list[tuple[str, str]]:
    """(option, path) of every file this run writes."""
    pairs = [
        ("--trajectory", args.trajectory),
        ("--keyframes", args.keyframes),
        ("--map", args.map),
        ("--rrd", args.rrd),
        ("--ar-video", getattr(args, "ar_video", None)),
    ]
    return [(option, path) for option, path in pairs if path]


def check_output_paths(args) -> None:
    """One line naming the option and path, before anything runs, for an output that cannot be written."""
    for option, path in output_options(args):
        directory = os.path.dirname(os.path.abspath(path))
        if os.path.isdir(path):
            raise InputError(f"{option} {path}: is a directory (give a file name)")
        if not os.path.isdir(directory):
            raise InputError(f"{option} {path}: directory {directory} does not exist")
        if not os.access(directory, os.W_OK | os.X_OK):
            raise InputError(f"{option} {path}: directory {directory} is not writable")
        if os.path.exists(path) and not os.access(path, os.W_OK):
            raise InputError(f"{option} {path}: the file exists and is not writable")


# -- atomic files ------------------------------------------------------------------------------------------
def fsync_directory(path: str) -> None:
    """Make a rename in ``path``'s directory durable."""
    fd = os.open(os.path.dirname(os.path.abspath(path)), os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_file(path: str) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def atomic_write(path: str, write) -> None:
    """``write(tmp)`` writes the whole file to ``tmp`` (same directory); it then replaces ``path`` durably."""
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(path)}.", suffix=".tmp", dir=directory)
    os.close(fd)
    try:
        write(tmp)
        fsync_file(tmp)
        os.chmod(tmp, _FILE_MODE)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    fsync_directory(path)


def write_trajectory(path: str, trajectory: list) -> None:
    """The whole trajectory, sorted by time, atomically."""
    t = np.array([p[0] for p in trajectory], dtype=np.float64)
    T = np.array([p[1] for p in trajectory], dtype=np.float64).reshape(-1, 4, 4)
    order = np.argsort(t, kind="stable")
    atomic_write(path, lambda tmp: write_tum(tmp, t[order], T[order], header=TRAJECTORY_HEADER))


def track_path(path: str, track: int) -> str:
    """Where a track not merged into the largest goes: ``traj.txt`` -> ``traj.track2.txt`` (poses),
    ``map.npz`` -> ``map.track2.npz`` (its map)."""
    root, ext = os.path.splitext(path)
    return f"{root}.track{track}{ext}"


def write_keyframes(path: str, snap) -> None:
    if snap is None or snap.n_keyframes == 0:
        atomic_write(path, lambda tmp: write_tum(tmp, np.zeros(0), np.zeros((0, 4, 4)), header="ptam keyframes (none)"))
        return
    t = np.array([k.timestamp for k in snap.keyframes])
    T_wc = np.linalg.inv(np.asarray(snap.kf_T_cw))
    atomic_write(path, lambda tmp: write_tum(tmp, t, T_wc, header=KEYFRAMES_HEADER))


def write_map(path: str, snap, camera, levels: int) -> None:
    """``save_map`` writes a temporary file, fsyncs it and renames it into place; the directory fsync makes the
    rename itself durable."""
    save_map(path, snap, camera, levels)
    fsync_directory(path)


def tum_lines(entries) -> str:
    """``(timestamp, T_wc)`` entries as TUM lines, formatted as ``write_tum`` does (exact float64 round trip)."""
    t = np.array([e[0] for e in entries], dtype=np.float64)
    T = np.array([e[1] for e in entries], dtype=np.float64).reshape(-1, 4, 4)
    values = np.concatenate([T[:, :3, 3], so3.to_quaternion(T[:, :3, :3])], axis=1)
    return "".join(f"{ti:.9f} " + " ".join(repr(float(v)) for v in row) + "\n" for ti, row in zip(t, values))


def _reason(option: str, path: str, e: BaseException) -> str:
    if isinstance(e, OSError):
        return f"{option} {path}: cannot write: {e.strerror or e}"
    return f"{option} {path}: {e}"


# -- the streamed trajectory -------------------------------------------------------------------------------
class _Rewrite:
    """In the stream's queue: the trajectory changed other than at its end (a reset, late poses inserted); the
    file is rewritten atomically from this copy of it."""

    def __init__(self, entries: list):
        self.entries = entries


class TrajectoryStream:
    """Observer ``f(outcome, system)`` that streams ``system.trajectory`` to ``path`` (see the module doc)."""

    def __init__(self, path: str, trajectory: list):
        self.path = path
        self._list = trajectory
        self._seen = 0  # entries of _list handed over ...
        self._last = None  # ... the last of them (its identity tells an append from an insertion)
        self._queue: collections.deque = collections.deque()
        self.written = 0  # poses in the file
        self.rewrites = 0
        self.error: OSError | None = None
        self._fd: int | None = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, _FILE_MODE)
        os.write(self._fd, f"# {TRAJECTORY_HEADER}\n{_COLUMNS}".encode())

    def __call__(self, outcome, system) -> None:
        """In the tracker's thread: hand the new entries to the flusher. Entries appended in time order go as
        they are (a deque append: no I/O, no lock); anything else (a reset replaced the list, an entry inserted
        before the end, one older than its predecessor) hands over a copy of the whole list, once."""
        trajectory = system.trajectory
        n = len(trajectory)
        if n == self._seen and trajectory is self._list:
            return
        if self._appended(trajectory, n):
            self._queue.extend(trajectory[self._seen : n])
        else:
            self._queue.append(_Rewrite(list(trajectory)))
        self._list, self._seen, self._last = trajectory, n, trajectory[-1] if n else None

    def _appended(self, trajectory: list, n: int) -> bool:
        """Only new entries at the end since the last frame, each newer than the one before."""
        if trajectory is not self._list or n < self._seen:
            return False
        if self._seen and trajectory[self._seen - 1] is not self._last:
            return False  # something was inserted before the end
        previous = self._last[0] if self._last is not None else -np.inf
        for t, _ in trajectory[self._seen : n]:
            if t <= previous:
                return False
            previous = t
        return True

    def flush(self) -> None:
        """In the flusher's thread: write what was queued in one write (or rewrite the file), then fsync."""
        if self._fd is None or self.error is not None:
            return
        batch: list = []
        try:
            while self._queue:
                item = self._queue.popleft()
                if isinstance(item, _Rewrite):
                    batch = []  # the copy holds them
                    self._rewrite(item.entries)
                else:
                    batch.append(item)
            self._write(batch)
            os.fsync(self._fd)
        except OSError as e:  # e.g. the disk is full: the end of the run rewrites the whole file
            self.error = e

    def _rewrite(self, entries: list) -> None:
        self.release()
        write_trajectory(self.path, entries)
        self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        self.written = len(entries)
        self.rewrites += 1

    def _write(self, batch) -> None:
        fd = self._fd
        if batch and fd is not None:
            data = tum_lines(batch).encode()
            while data:
                data = data[os.write(fd, data) :]
            self.written += len(batch)

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def close(self, trajectory: list) -> None:
        """The last flush; the file is rewritten (atomically) only if it does not hold the whole trajectory."""
        self.flush()
        self.release()
        if self.error is not None or self.written != len(trajectory) or trajectory is not self._list:
            write_trajectory(self.path, trajectory)
        else:
            fsync_directory(self.path)


# -- the run's outputs -------------------------------------------------------------------------------------
class RunOutputs:
    """The trajectory stream, the checkpoint thread and the final writes of one ``ptam run``."""

    def __init__(self, args, cfg, camera):
        self.trajectory_path, self.keyframes_path, self.map_path = args.trajectory, args.keyframes, args.map
        self.camera = camera
        self.levels = cfg.image.levels
        self.every = cfg.system.map_checkpoint_keyframes
        self.interval_s = cfg.system.output_flush_s
        self.stream: TrajectoryStream | None = None
        self.checkpoints = 0
        self._checkpointed = 0  # keyframes in the last checkpoint
        self._checkpoint_error: str | None = None
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    def start(self, system) -> RunOutputs:
        """Open the trajectory file (truncating it) and start the flusher and checkpoint threads."""
        if self.trajectory_path:
            try:
                self.stream = TrajectoryStream(self.trajectory_path, system.trajectory)
            except OSError as e:
                raise InputError(_reason("--trajectory", self.trajectory_path, e)) from None
            system.observers.append(self.stream)
            self._spawn("ptam-trajectory", self.stream.flush)
        if self.every > 0 and (self.keyframes_path or self.map_path):
            self._spawn("ptam-checkpoint", lambda: self._checkpoint(system))
        return self

    def _spawn(self, name: str, work) -> None:
        def loop() -> None:
            while not self._stop.wait(self.interval_s):
                work()

        thread = threading.Thread(target=loop, name=name, daemon=True)
        thread.start()
        self._threads.append(thread)

    def _checkpoint(self, system) -> None:
        """In the checkpoint thread: rewrite keyframes and map once the map has grown by ``every`` keyframes."""
        snap = system.mapper.snapshot
        n = snap.n_keyframes if snap is not None else 0
        if n < self._checkpointed:  # a reset: the next map counts from zero
            self._checkpointed = 0
        if n == 0 or n - self._checkpointed < self.every:
            return
        try:
            if self.keyframes_path:
                write_keyframes(self.keyframes_path, snap)
            if self.map_path:
                write_map(self.map_path, snap, self.camera, self.levels)
        except (OSError, PtamError) as e:
            if self._checkpoint_error is None:
                self._checkpoint_error = str(e)
                log.warning("checkpoint failed (the end of the run tries again): %s", e)
            return
        self._checkpointed = n
        self.checkpoints += 1

    def abandon(self) -> None:
        """The run did not start after all: stop the threads and close the stream as it is."""
        self._stop_threads()
        if self.stream is not None:
            self.stream.flush()
            self.stream.release()

    def _stop_threads(self) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join()
        self._threads = []

    def close(self, system) -> list[str]:
        """Stop the threads, then finish every output; returns one line per output that could not be written."""
        self._stop_threads()
        snap = system.mapper.snapshot
        failures = []
        jobs = [
            ("--trajectory", self.trajectory_path, lambda: self._finish_trajectory(system)),
            ("--keyframes", self.keyframes_path, lambda: write_keyframes(self.keyframes_path, snap)),
            ("--map", self.map_path, lambda: self._finish_map(snap, system)),
        ]
        for option, path, job in jobs:
            if not path:
                continue
            try:
                job()
            except (OSError, PtamError) as e:
                failures.append(_reason(option, path, e))
        return failures

    def _finish_trajectory(self, system) -> None:
        """The largest track's poses (Gauglitz §4.4: tracks merged into it included); each track that was never
        merged into it goes to a file of its own beside it, in its own frame and scale (:func:`track_path`)."""
        if self.stream is None:
            write_trajectory(self.trajectory_path, system.trajectory)
        else:
            self.stream.close(system.trajectory)
        for track, poses in system.other_tracks.items():
            write_trajectory(track_path(self.trajectory_path, track), poses)

    def _finish_map(self, snap, system) -> None:
        """The largest track's map (:meth:`_finish_trajectory`); each unmerged track's map beside it."""
        if snap is None or snap.n_keyframes == 0:
            print(f"ptam: no map to write to {self.map_path} (no map was built)", file=sys.stderr)
            return
        write_map(self.map_path, snap, self.camera, self.levels)
        for track, mapper in system.track_mappers.items():
            if track != system.track_id and mapper.snapshot is not None and mapper.snapshot.n_keyframes:
                write_map(track_path(self.map_path, track), mapper.snapshot, self.camera, self.levels)


def finish_video(path: str | None) -> None:
    """After the AR worker released its writer: make the video and its directory entry durable."""
    if path and os.path.isfile(path):
        fsync_file(path)
        fsync_directory(path)
