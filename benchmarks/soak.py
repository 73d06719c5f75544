"""Soak test of ``ptam run`` (not part of CI): a scene replayed in a loop, in realtime, for many minutes, with the
viewer recording to an ``.rrd`` and every output asked for; then SIGINT, and a check that everything was written.

    python benchmarks/soak.py --minutes 20                # the bundled two_wall scene, looped
    python benchmarks/soak.py --minutes 3 --rrd /tmp/soak.rrd --out /tmp/soak

The scene is rendered once (``ptam.synthetic.ensure_sequence``, into the usual cache) and looped by an ``rgb.txt``
generated in a temporary folder: the same frames again and again, with increasing timestamps. The camera jumps
from the end of the path back to its start at every loop, so each loop also exercises a tracking loss and a
relocalisation. The recording is written as a live camera's is (``viewer.rrd_footer=never``: rerun's chunk
manifest, which grows in memory for as long as the file is open, is left out). ``ptam run`` runs as a subprocess
(the real command line); every ``--report-s`` seconds a row shows its resident memory (``/proc/PID/status``
VmRSS), the ``.rrd`` size, the poses already streamed to the trajectory file and the map file's size
(checkpoints). At the end: frames, frames dropped, and whether the trajectory, keyframes, map and recording were
all written. Exit status 0 when they were.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from ptam.config import load_config
from ptam.eval import read_tum
from ptam.map.map_file import load_map
from ptam.synthetic import ensure_sequence

MB = 1024 * 1024


def looped_dataset(sequence: Path, seconds: float, out: Path) -> int:
    """A TUM folder in ``out`` replaying ``sequence`` for at least ``seconds``; returns its frame count."""
    rows = [line.split() for line in (sequence / "rgb.txt").read_text().splitlines() if not line.startswith("#")]
    stamps = [float(t) for t, _ in rows]
    dt = (stamps[-1] - stamps[0]) / max(len(stamps) - 1, 1)
    period = stamps[-1] - stamps[0] + dt
    loops = math.ceil(seconds / period) + 1
    with open(out / "rgb.txt", "w") as f:
        f.write(f"# {sequence.name} looped {loops} times\n")
        for k in range(loops):
            for t, (_, name) in zip(stamps, rows, strict=True):
                f.write(f"{t + k * period:.9f} {sequence / name}\n")
    (out / "camera.yaml").write_text((sequence / "camera.yaml").read_text())
    return loops * len(rows)


def rss_mb(pid: int) -> float:
    """Resident memory of process ``pid`` from /proc (no psutil)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return float("nan")


def poses_on_disk(path: Path) -> int:
    try:
        with open(path) as f:
            return sum(1 for line in f if line.strip() and not line.startswith("#"))
    except OSError:
        return 0


def size_mb(path: Path) -> float:
    return path.stat().st_size / MB if path.exists() else 0.0


def monitor(proc, outputs: dict, minutes: float, report_s: float) -> list[tuple]:
    """Rows (seconds, RSS MB, rrd MB, poses on disk, map MB) every ``report_s`` until ``minutes`` have passed."""
    rows = []
    start = time.monotonic()
    print(f"{'t [s]':>7} {'RSS [MB]':>9} {'rrd [MB]':>9} {'poses on disk':>14} {'map [MB]':>9}", flush=True)
    next_report = 0.0
    while proc.poll() is None:
        elapsed = time.monotonic() - start
        if elapsed >= next_report or elapsed >= 60 * minutes:
            row = (
                elapsed,
                rss_mb(proc.pid),
                size_mb(outputs["rrd"]),
                poses_on_disk(outputs["trajectory"]),
                size_mb(outputs["map"]),
            )
            rows.append(row)
            print(f"{row[0]:7.0f} {row[1]:9.1f} {row[2]:9.1f} {row[3]:14d} {row[4]:9.2f}", flush=True)
            next_report += report_s
        if elapsed >= 60 * minutes:
            break
        time.sleep(0.5)
    return rows


def summary_numbers(stdout: str) -> dict:
    words = stdout.split()
    found = {}
    for key, label in (("frames", "frames"), ("tracked", "tracked"), ("keyframes", "keyframes"), ("dropped", "frames")):
        for i, w in enumerate(words[:-1]):
            if w == label and (key != "dropped" or (i > 0 and words[i - 1] == "dropped")):
                found[key] = int(words[i + 1])
                break
    return found


def check_outputs(outputs: dict, numbers: dict, image_cfg) -> list[str]:
    """What is wrong with the written outputs (empty when all are complete)."""
    problems = []
    t, _ = read_tum(outputs["trajectory"])
    if len(t) != numbers.get("tracked"):
        problems.append(f"trajectory holds {len(t)} poses, the summary says {numbers.get('tracked')} tracked")
    if len(t) > 1 and not (t[1:] > t[:-1]).all():
        problems.append("trajectory timestamps are not increasing")
    if len(read_tum(outputs["keyframes"])[0]) != numbers.get("keyframes"):
        problems.append("keyframes file does not hold every keyframe")
    if load_map(outputs["map"], image_cfg).map.n_keyframes != numbers.get("keyframes"):
        problems.append("map file does not hold every keyframe")
    if size_mb(outputs["rrd"]) == 0:
        problems.append("the .rrd recording is empty")
    return problems


def growth_mb_per_min(rows: list[tuple], column: int) -> float:
    """Least-squares slope over the second half of the run (after warm-up), in MB per minute."""
    half = [r for r in rows if r[0] >= rows[-1][0] / 2]
    if len(half) < 2:
        return float("nan")
    n = len(half)
    mx = sum(r[0] for r in half) / n
    my = sum(r[column] for r in half) / n
    sxx = sum((r[0] - mx) ** 2 for r in half)
    return 60 * sum((r[0] - mx) * (r[column] - my) for r in half) / sxx if sxx else float("nan")


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default="two_wall", help="bundled scene name or scene YAML (default two_wall)")
    p.add_argument("--minutes", type=float, default=20.0, help="how long to run (default 20)")
    p.add_argument("--rrd", help="the viewer's recording (default: in --out)")
    p.add_argument("--out", help="folder for the outputs (default: a temporary folder, removed unless --keep)")
    p.add_argument("--report-s", type=float, default=30.0, help="seconds between rows (default 30)")
    p.add_argument("--keep", action="store_true", help="keep the temporary folder")
    p.add_argument("--set", action="append", default=[], dest="overrides", help="passed on to ptam run")
    return p.parse_args(argv)


def run(args, work: Path) -> int:
    cfg = load_config()
    sequence = Path(ensure_sequence(args.scene, cfg.synthetic))
    dataset = work / "looped"
    dataset.mkdir(exist_ok=True)
    frames = looped_dataset(sequence, 60 * args.minutes, dataset)
    outputs = {
        "trajectory": work / "trajectory.txt",
        "keyframes": work / "keyframes.txt",
        "map": work / "map.npz",
        "rrd": Path(args.rrd) if args.rrd else work / "soak.rrd",
    }
    argv = [sys.executable, "-m", "ptam", "run", "--dataset", str(dataset), "--mode", "realtime"]
    argv += [a for key, path in outputs.items() for a in (f"--{key}", str(path))]
    argv += ["--set", "viewer.rrd_footer=never"]  # an hour-long session is a live camera's, not a dataset's
    argv += [a for o in args.overrides for a in ("--set", o)]
    env = {**os.environ, "DISPLAY": "", "WAYLAND_DISPLAY": ""}
    print(f"soak: {args.scene} looped ({frames} frames queued) for {args.minutes:g} min, outputs in {work}")
    with open(work / "stdout.txt", "w+") as out, open(work / "stderr.txt", "w+") as err:
        proc = subprocess.Popen(argv, stdout=out, stderr=err, text=True, env=env)
        rows = monitor(proc, outputs, args.minutes, args.report_s)
        ended_early = proc.poll() is not None
        proc.send_signal(signal.SIGINT)
        t0 = time.monotonic()
        code = proc.wait(timeout=300)
        shutdown_s = time.monotonic() - t0
        out.seek(0)
        stdout = out.read()
        err.seek(0)
        stderr = err.read()
    return report(args, rows, outputs, stdout, stderr, code, shutdown_s, ended_early, cfg)


def report(args, rows, outputs, stdout, stderr, code, shutdown_s, ended_early, cfg) -> int:
    numbers = summary_numbers(stdout)
    print(stdout.strip())
    print(
        f"exit code {code} after SIGINT (expected 130), shut down in {shutdown_s:.1f} s; "
        f"frames {numbers.get('frames')}, dropped {numbers.get('dropped', 0)}"
    )
    if rows:
        print(
            f"RSS {rows[0][1]:.0f} -> {rows[-1][1]:.0f} MB (second half: {growth_mb_per_min(rows, 1):+.1f} MB/min); "
            f".rrd {rows[-1][2]:.0f} MB ({growth_mb_per_min(rows, 2):+.1f} MB/min)"
        )
    problems = [] if code == 130 else [f"exit code {code}: {stderr.strip().splitlines()[-1:]}"]
    if ended_early:
        problems.append("ptam run ended before the time was up")
    try:
        problems += check_outputs(outputs, numbers, cfg.image)
    except Exception as e:  # a missing or unreadable output is the finding, not a crash of the soak
        problems.append(str(e))
    print("outputs: all written and complete" if not problems else "PROBLEMS: " + "; ".join(problems))
    return 0 if not problems else 1


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.out:
        work = Path(args.out)
        work.mkdir(parents=True, exist_ok=True)
        return run(args, work)
    tmp = tempfile.TemporaryDirectory(prefix="ptam-soak-")
    try:
        return run(args, Path(tmp.name))
    finally:
        if args.keep:
            print(f"soak: kept {tmp.name}")
        else:
            tmp.cleanup()


if __name__ == "__main__":
    sys.exit(main())
