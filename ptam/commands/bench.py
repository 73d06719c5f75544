"""``ptam bench WHAT [SCENE]``: the papers' timing tables measured on this machine (PTAM Tables 1 and 2, Agility
§6–§7), and ``accuracy``: the accuracy suite in every run mode.

Each benchmark is a ``run_*_benchmark(cfg, scene)`` in ``ptam.bench``; ``all`` runs PTAM's two tables. Without
a SCENE a benchmark runs on two_wall, ``accuracy`` on its whole suite.
"""

from __future__ import annotations

import importlib

BENCHMARKS = {
    "tracking": ("tracking_timing", "run_tracking_benchmark"),
    "mapping": ("system_run", "run_mapping_benchmark"),
    "agility": ("agility_timing", "run_agility_benchmark"),
    "ar": ("ar_timing", "run_ar_benchmark"),
    "accuracy": ("accuracy", "run_accuracy_benchmark"),
}
ALL = ("tracking", "mapping")
DEFAULT_SCENE = "two_wall"
DEFAULT_SCENES = {"accuracy": "suite"}  # ptam.bench.accuracy.SUITE_NAME: every scene of the accuracy suite


def _run(name: str, cfg, scene: str | None) -> None:
    module, func = BENCHMARKS[name]
    scene = scene or DEFAULT_SCENES.get(name, DEFAULT_SCENE)
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
