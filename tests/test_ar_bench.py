"""``ptam bench ar``: the per-scene rows and the one machine-readable summary line (timings are not asserted)."""

import re

from ptam.bench.ar_timing import run_ar_benchmark
from ptam.config import load_config


def test_bench_ar_reports_every_scene_and_the_summary_line():
    lines = []
    # A logging queue that never fills in 60 frames: the viewer then draws AR frames however loaded the machine
    # (with the default queue, a slow logging thread can leave no room for any).
    cfg = load_config(overrides=["viewer.queue_size=1000"])
    result = run_ar_benchmark(cfg, "two_wall_short", out=lines.append, frames=60, realtime_runs=1)
    assert re.fullmatch(r"ar_render_ms=\d+\.\d\d", lines[-1])
    assert set(result["scenes"]) == {"eyes", "game", "grid"} and result["frames"] >= 15
    assert result["ar_render_ms"] == max(r["mean"] for r in result["scenes"].values()) > 0
    assert all(v > 0 for v in result["encode_ms"].values())
    viewer = result["viewer"]
    assert viewer["off"]["ar_cpu_ms"] == 0.0 and viewer["grid"]["ar_drawn"] > 0 and viewer["grid"]["ar_cpu_ms"] > 0
    live = result["realtime"]
    assert len(live) == 2 and all(r["low"] <= r["median"] <= r["high"] and r["median"] > 0 for r in live.values())
