"""``ptam bench ba``: the Table 2 layout and its one machine-readable summary line (timings are not asserted)."""

import re

from ptam.bench import ba_edgelets as bench_edgelets
from ptam.bench import ba_timing as bench_ba
from ptam.config import default_config


def test_bench_reports_buckets_and_summary_line(monkeypatch):
    monkeypatch.setattr(bench_ba, "BENCH_KEYFRAMES", (10, 50, 100))
    monkeypatch.setattr(bench_ba, "LOCAL_REPEATS", 1)
    monkeypatch.setattr(bench_edgelets, "EDGELET_BENCH_KEYFRAMES", (10,))
    monkeypatch.setattr(bench_edgelets, "EDGELET_BENCH_REPEATS", 1)
    lines = []
    result = bench_ba.run_ba_benchmark(default_config(), out=lines.append)
    summary = [ln for ln in lines if ln.startswith("local_ba_ms_2_49=")]
    assert len(summary) == 1 and lines[-1] == summary[0]
    keys = ("local_ba_ms_2_49", "global_ba_ms_2_49", "global_ba_ms_50_99", "global_ba_ms_100_149")
    assert re.fullmatch(" ".join(rf"{k}=\d+\.\d" for k in keys), summary[0])
    assert all(result[k] > 0 for k in keys)
    # Every map size converged; the 100-keyframe map has 40 points per keyframe pair.
    assert [r["keyframes"] for r in result["rows"]] == [10, 50, 100]
    assert all(r["global_converged"] for r in result["rows"]) and result["rows"][2]["points"] == 40 * 99
    # Agility §9.2's comparison: the same 10-keyframe map without and with one edgelet per 5 points.
    (e,) = result["edgelet_rows"]
    assert e["keyframes"] == 10 and e["edgelets"] == e["points"] // 5 and e["edgelet_measurements"] > 2 * e["edgelets"]
    kinds = ("global", "global_edgelets", "local", "local_edgelets")
    assert all(e[f"{k}_cpu_ms"] > 0 and e[f"{k}_iterations"] > 0 for k in kinds)
    assert any(ln.startswith("edgelets (Agility §9.2") for ln in lines)
