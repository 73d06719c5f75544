"""The edgelet job per keyframe, replayed (Agility §9.2: "performing edge extraction and adding edgelets can
require up to 20ms per keyframe"), not part of CI. Each scene runs in sync mode; the map is copied just before
each of the mapper's edgelet jobs (keyframe images shared, as the mapper's image cache sees them), and after the
run the jobs are run again on those copies, in order, ``--repeats`` times. Per scene it prints the median over
jobs of each job's smallest CPU time and of its time in the run, and beside them the median CPU time in the run of
the rest of each keyframe's integration, the points' part (PTAM §6.2: the tracker's measurements, re-finding the
map's points, the epipolar search for new ones). Agility §9.2 puts the edgelet job at "twice as long as it takes
to add points", a ratio that does not depend on the machine's speed. Each time is split into the job's last step,
the §5.2 visibility tables of every measurement it made (which §5.2 says the map-maker builds, and §9.2 does not
say whether its 20 ms include; the job's own wall-time record of that single-threaded step), and the rest, edge
extraction and adding edgelets in §9.2's words. The replay also times what the mapper does later, when idle, with
each job's new edgelets: measuring them in the old keyframes (§4.4; ``measure_newly_made``, as PTAM's
``ReFindNewlyMade`` re-finds new points in old keyframes outside adding them).

    python benchmarks/edgelet_job.py                            # desk_bricks, two_wall, desk_table, desk_corner
    python benchmarks/edgelet_job.py --scenes bricks_blur --repeats 5

The replay times the process's CPU, so work a library hands to threads of its own counts (ptam runs OpenCV on
one thread; with its pool the replay read 19.5 ms where the job's thread alone read 15.9). The run times the
mapper thread's CPU, the tracker sharing the process. In the run a job follows the tracker's frames, which leave
the CPU's caches cold for it, and this machine's speed drifts from one run to the next: the replay's figure is
the one to compare between commits, the run's (``ptam run`` prints it as ``edgelet job ms median``) what a
session sees.
"""

from __future__ import annotations

import argparse
import copy
import time

import numpy as np

from ptam.bench.accuracy import run_accuracy
from ptam.config import load_config
from ptam.mapping import edgelet_work, map_maker
from ptam.mapping.edgelet_images import EdgeImages
from ptam.mapping.edgelet_mapping import integrate_keyframe
from ptam.mapping.edgelet_measurements import measure_newly_made
from ptam.vocabulary import RunMode

DEFAULT_SCENES = "desk_bricks,two_wall,desk_table,desk_corner"


def _copy(m, images: dict) -> object:
    """A deep copy of map ``m`` whose keyframe images are one array per keyframe across all copies."""
    memo = {}
    for k, kf in enumerate(m.keyframes):
        image = kf.pyramid.levels[0]
        memo[id(image)] = images.setdefault(k, image)
    return copy.deepcopy(m, memo)


def _recorded(jobs: list, images: dict, points: list) -> None:
    """Wrap the mapper's edgelet job (the map copied before it, its CPU ms in the run and the ms of its tables,
    ``EdgeletJob.tables_ms``) and its keyframe integration (the CPU ms of the rest, the points' part, into
    ``points``)."""
    inside = [0.0]  # CPU s of the wrapped job, copy included, inside the current integration

    def recorded(m, camera, cfg, k, t, cache=None):
        w = time.thread_time()
        state = (_copy(m, images), camera, k, t)
        c = time.thread_time()
        out = integrate_keyframe(m, camera, cfg, k, t, cache)
        jobs.append((state, 1e3 * (time.thread_time() - c), out.tables_ms))
        inside[0] += time.thread_time() - w
        return out

    integrate = map_maker.MapMaker._integrate

    def integrated(self, request):
        inside[0] = 0.0
        c = time.thread_time()
        integrate(self, request)
        if not request.panorama:
            points.append(1e3 * (time.thread_time() - c - inside[0]))

    edgelet_work.integrate_keyframe = recorded
    map_maker.MapMaker._integrate = integrated


def _replayed(jobs: list, cfg, repeats: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each job's smallest CPU ms over ``repeats`` in-order replays, one image cache per replay, the ms of its
    tables (``EdgeletJob.tables_ms``) in that replay, and the smallest CPU ms of measuring its new edgelets in the
    old keyframes after it (``measure_newly_made``, the mapper's idle-time work)."""
    times = np.empty((repeats, len(jobs)))
    table_ms = np.empty((repeats, len(jobs)))
    old_ms = np.empty((repeats, len(jobs)))
    for r in range(repeats):
        cache = EdgeImages(cfg.edgelets)
        for j, ((m, camera, k, t), *_) in enumerate(jobs):
            m = copy.deepcopy(m, {id(kf.pyramid.levels[0]): kf.pyramid.levels[0] for kf in m.keyframes})
            first = m.edgelets.n_total
            c = time.process_time()
            job = integrate_keyframe(m, camera, cfg, k, t, cache)
            times[r, j] = 1e3 * (time.process_time() - c)
            table_ms[r, j] = job.tables_ms
            c = time.process_time()
            measure_newly_made(m, camera, cfg, np.arange(first, m.edgelets.n_total), 0, lambda: False)
            old_ms[r, j] = 1e3 * (time.process_time() - c)
    best = (times.argmin(axis=0), np.arange(len(jobs)))
    return times[best], table_ms[best], old_ms.min(axis=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=DEFAULT_SCENES, help="comma-separated scene names")
    ap.add_argument("--repeats", type=int, default=3, help="replays of every job (the smallest time is kept)")
    args = ap.parse_args()
    cfg = load_config(None)
    jobs: list = []
    images: dict = {}
    points: list = []
    _recorded(jobs, images, points)
    print(
        "scene            jobs | replayed CPU ms median (min-max), tables, rest, old keyframes | "
        "in the run CPU ms median: job, tables, rest, points' part, ratio"
    )
    for scene in args.scenes.split(","):
        jobs.clear()
        images.clear()
        points.clear()
        run_accuracy(cfg, scene, RunMode.SYNC)
        replay, replay_tables, old = _replayed(jobs, cfg, max(args.repeats, 1))
        live, live_tables = (np.array([job[i] for job in jobs]) for i in (1, 2))
        pts = np.median(points)
        span = f"({replay.min():.1f}-{replay.max():.1f})"
        print(
            f"{scene:16s} {len(jobs):4d} | {np.median(replay):8.1f} {span:>13s} "
            f"{np.median(replay_tables):6.1f} {np.median(replay - replay_tables):6.1f} {np.median(old):6.1f} | "
            f"{np.median(live):8.1f} {np.median(live_tables):6.1f} {np.median(live - live_tables):6.1f} "
            f"{pts:8.1f} {np.median(live) / pts:8.2f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
