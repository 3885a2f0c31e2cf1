"""Cost of the figures and the HTML report: whole ``chapter4.py`` processes, side by side.

    python benchmarks/report.py [--runs N]

Runs, as fresh processes the way a user does (bytecode cached, one warm-up run of each),
interleaved so that a change in the machine's load hits every variant alike:

- ``default``: ``chapter4.py`` (four PNG figures and report.html);
- ``no-plots``: ``chapter4.py --no-plots`` (report.html with its 3D view, no figures);
- ``bare``: ``chapter4.py --no-plots --no-report`` (point cloud and JSON only).

Prints a markdown table of the median and fastest wall-clock seconds of each, their ratio
to ``bare`` and to ``no-plots`` (issue #23's goal: default at most 2x), the median stage
timings the command recorded in reconstruction.json, and the output sizes. Timings on a
shared machine vary from run to run; compare the rows of one run.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
VARIANTS = {
    "default": [],
    "no-plots": ["--no-plots"],
    "bare": ["--no-plots", "--no-report"],
}


def run_once(args: list[str], out: Path, env: dict[str, str]) -> float:
    cmd = [sys.executable, str(REPO / "chapter4.py"), "--out", str(out), "-q", *args]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True, env=env)
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=11, help="runs of each variant (11)")
    args = parser.parse_args(argv)
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # time processes as users run them
    times: dict[str, list[float]] = {k: [] for k in VARIANTS}
    stages: dict[str, dict[str, list[float]]] = {k: {} for k in VARIANTS}
    sizes: dict[str, int] = {}
    with tempfile.TemporaryDirectory() as tmp:
        outs = {k: Path(tmp) / k for k in VARIANTS}
        for name, extra in VARIANTS.items():  # warm-up: bytecode, file cache
            run_once(extra, outs[name], env)
        for i in range(args.runs):
            for name, extra in VARIANTS.items():
                times[name].append(run_once(extra, outs[name], env))
                recorded = json.loads((outs[name] / "reconstruction.json").read_text())
                for stage, seconds in recorded["timings_s"].items():
                    stages[name].setdefault(stage, []).append(seconds)
            print(f"run {i + 1}/{args.runs}: " + ", ".join(
                f"{k} {v[-1]:.2f} s" for k, v in times.items()), file=sys.stderr)
        for path in sorted(outs["default"].iterdir()):
            sizes[path.name] = path.stat().st_size
    med = {k: statistics.median(v) for k, v in times.items()}
    low = {k: min(v) for k, v in times.items()}
    print(f"{args.runs} interleaved runs of each, {time.strftime('%Y-%m-%d %H:%M')}, "
          f"{os.cpu_count()} cores\n")
    print("| variant | median s | fastest s | median / bare | fastest / bare | "
          "median / no-plots | fastest / no-plots |")
    print("|---|---|---|---|---|---|---|")
    for name in VARIANTS:
        print(f"| {name} | {med[name]:.2f} | {low[name]:.2f} | "
              f"{med[name] / med['bare']:.2f} | {low[name] / low['bare']:.2f} | "
              f"{med[name] / med['no-plots']:.2f} | {low[name] / low['no-plots']:.2f} |")
    print("\nMedian stage seconds recorded by the command (plots: figures drawn and encoded "
          "while the 3D view's data are prepared; report: the page):\n")
    names = sorted({s for v in stages.values() for s in v},
                   key=lambda s: list(stages["default"]).index(s)
                   if s in stages["default"] else 99)
    print("| variant | " + " | ".join(names) + " |")
    print("|---|" + "---|" * len(names))
    for variant, recorded in stages.items():
        print(f"| {variant} | " + " | ".join(
            f"{statistics.median(recorded[s]):.3f}" if s in recorded else "-" for s in names)
            + " |")
    print("\nOutputs of the default run:\n")
    print("| file | bytes |")
    print("|---|---|")
    for name, size in sizes.items():
        print(f"| {name} | {size:,} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
