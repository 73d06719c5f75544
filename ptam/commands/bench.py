"""``ptam bench WHAT``: the paper's timing tables measured on this machine (PTAM Tables 1 and 2)."""

from __future__ import annotations

from ..errors import PtamError


def main(args, cfg) -> int:
    if args.what == "ba":
        from ..eval.bench_ba import run_ba_benchmark
        run_ba_benchmark(cfg)
        return 0
    if args.what == "tracking":
        from ..eval.bench_tracking import run_tracking_benchmark
        run_tracking_benchmark(cfg, args.scene)
        return 0
    if args.what == "mapping":
        from ..eval.bench_mapping import run_mapping_benchmark
        run_mapping_benchmark(cfg, args.scene)
        return 0
    if args.what == "agility":
        from ..eval.bench_agility import run_agility_benchmark
        run_agility_benchmark(cfg, args.scene)
        return 0
    if args.what == "ar":
        from ..eval.bench_ar import run_ar_benchmark
        run_ar_benchmark(cfg, args.scene)
        return 0
    if args.what == "all":
        from ..eval.bench_mapping import run_mapping_benchmark
        from ..eval.bench_tracking import run_tracking_benchmark
        run_tracking_benchmark(cfg, args.scene)
        print()
        run_mapping_benchmark(cfg, args.scene)
        return 0
    raise PtamError(f"ptam bench {args.what}: not implemented yet")
