"""``ptam bench WHAT``: the papers' timing tables measured on this machine (PTAM Tables 1 and 2, Agility §6–§7).

Each benchmark is a ``run_*_benchmark(cfg, scene)`` in ``ptam.bench``; ``all`` runs PTAM's two tables.
"""

from __future__ import annotations

import importlib

BENCHMARKS = {
    "tracking": ("tracking_timing", "run_tracking_benchmark"),
    "mapping": ("system_run", "run_mapping_benchmark"),
    "agility": ("agility_timing", "run_agility_benchmark"),
    "ar": ("ar_timing", "run_ar_benchmark"),
}
ALL = ("tracking", "mapping")


def _run(name: str, cfg, scene: str) -> None:
    module, func = BENCHMARKS[name]
    getattr(importlib.import_module(f"ptam.bench.{module}"), func)(cfg, scene)


def main(args, cfg) -> int:
    if args.what == "ba":  # synthetic PTAM-shaped maps, no scene
        from ..bench.ba_timing import run_ba_benchmark

        run_ba_benchmark(cfg)
    elif args.what == "all":
        for i, name in enumerate(ALL):
            if i:
                print()
            _run(name, cfg, args.scene)
    else:
        _run(args.what, cfg, args.scene)
    return 0
