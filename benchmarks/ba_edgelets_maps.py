"""Edgelets' cost in bundle adjustment on the maps ptam builds (Agility §9.2: "edgelets add a 25% extra processing
burden"), not part of CI. Each scene runs in sync mode; every adjustment the mapper makes with edgelets is run again
on the same inputs with and without them (``_timed_twice``), ``EDGELET_BENCH_REPEATS`` times each in turn, the fastest
run of each kept (as ``ptam bench ba``'s edgelet rows), and the CPU times and LM iterations of both are summed per
scene and kind (local: at most ``bundle.local_neighbours`` + 1 free keyframes; global: the rest).

    python benchmarks/ba_edgelets_maps.py                       # desk_bricks, two_wall, desk_table, desk_corner
    python benchmarks/ba_edgelets_maps.py --scenes desk_blur

``ptam bench ba`` measures the same ratio on synthetic maps with one edgelet per five points; here the maps have
whatever share of edgelets their scenes give (desk_bricks about one edgelet measurement per 3-4 point
measurements, the other desk scenes far fewer).
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict

import numpy as np

from ptam.bench.accuracy import run_accuracy
from ptam.bench.ba_edgelets import EDGELET_BENCH_REPEATS
from ptam.config import load_config
from ptam.mapping.bundle import Bundle
from ptam.vocabulary import RunMode

DEFAULT_SCENES = "desk_bricks,two_wall,desk_table,desk_corner"


def _timed_twice(totals: dict) -> None:
    """Wrap ``Bundle.adjust``: the mapper's call with edgelets runs as usual, then the same adjustment is timed again
    with and without edgelets, in alternating order, ``EDGELET_BENCH_REPEATS`` times, the fastest run of each kept
    (timed once, a scene's ratios moved ±10 % from one run to the next). Timing the mapper's own call instead
    favoured points alone: that call runs on caches the tracker left cold (and the first of a run loads the edgelet
    kernels), and the repeat without edgelets then found the map's arrays warm (desk_bricks' global adjustments
    1.8x-4.0x from one run to the next)."""
    adjust = Bundle.adjust
    calls = [0]

    def twice(self, *args, **kw):
        res = adjust(self, *args, **kw)
        if kw.get("edgelets") is None or res.aborted:
            return res
        ms, runs = {"with": np.inf, "alone": np.inf}, {}
        order = ("with", "alone") if calls[0] % 2 else ("alone", "with")
        calls[0] += 1
        for _ in range(EDGELET_BENCH_REPEATS):
            for name in order:
                c = time.thread_time()
                runs[name] = adjust(
                    self, *args, **dict(kw, abort=None, edgelets=kw["edgelets"] if name == "with" else None)
                )
                ms[name] = min(ms[name], 1e3 * (time.thread_time() - c))
        fixed = np.asarray(args[6])
        kind = "local" if (~fixed).sum() <= self.cfg.local_neighbours + 1 < len(fixed) else "global"
        row = totals[kind]
        for key, value in (
            ("n", 1),
            ("with_ms", ms["with"]),
            ("with_its", runs["with"].iterations),
            ("alone_ms", ms["alone"]),
            ("alone_its", runs["alone"].iterations),
            ("point_meas", runs["alone"].n_inliers),
            ("edgelet_meas", res.n_edgelet_inliers),
        ):
            row[key] += value
        return res

    Bundle.adjust = twice


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=DEFAULT_SCENES, help="comma-separated scene names")
    scenes = ap.parse_args().scenes.split(",")
    cfg = load_config(None)
    totals: dict = defaultdict(lambda: defaultdict(float))
    _timed_twice(totals)
    print("scene          kind    BAs  meas pts:edg | with edgelets ms (its) | points alone ms (its) | ratio  /it")
    for scene in scenes:
        totals.clear()
        run_accuracy(cfg, scene, RunMode.SYNC)
        for kind in ("local", "global"):
            r = totals.get(kind)
            if not r:
                continue
            ratio = r["with_ms"] / r["alone_ms"]
            per_it = ratio * r["alone_its"] / max(r["with_its"], 1)
            meas = r["point_meas"] / max(r["edgelet_meas"], 1)
            with_e = f"{r['with_ms']:13.1f} ({int(r['with_its']):4d})"
            alone = f"{r['alone_ms']:12.1f} ({int(r['alone_its']):4d})"
            head = f"{scene:14s} {kind:6s} {int(r['n']):4d} {meas:7.1f}:1"
            print(f"{head} | {with_e} | {alone} | {ratio:5.2f} {per_it:5.2f}", flush=True)


if __name__ == "__main__":
    main()
