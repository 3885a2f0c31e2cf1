"""What keeping freed memory for reuse saves, and costs: the command-line tools with and without it.

    python benchmarks/freed_memory.py [--runs 21] [--views-runs 3] [--full-runs 3]
                                      [--scenes ...] [--workers N]

The command-line tools let glibc's malloc keep large freed blocks for reuse
(:mod:`scene3D.memory`): blocks up to 32 MiB come from the heap, and up to 512 MiB of
freed heap is kept. A malloc setting of the user's turns that off, which is how the
variants are made: as the command sets it; 64 MiB kept (the most glibc keeps by itself,
its own ceilings, as tunables); and glibc's defaults (``GLIBC_TUNABLES=
glibc.malloc.perturb=0``, a malloc tunable at glibc's own default value; ``MALLOC_TOP_PAD_``
at its default would not do: setting it stops glibc from raising its thresholds by
itself). Whole processes as users run them (bytecode cached), interleaved so that the
shared machine's load hits every variant alike:

- ``chapter4.py --no-plots`` on the book pair (768 px), ``--runs`` times each after one
  untimed warm-up, and the plain-OpenCV script of ``two_view.py``: medians and fastest
  runs, and their ratios to the plain script;
- ``scene3d reconstruct-views`` of each scene (1536 px, the Strecha calibration,
  ``--no-plots --no-report``), ``--views-runs`` times each: wall time, the features stage
  (``timings_s`` of reconstruction.json) and the peak memory of the largest process
  (``ru_maxrss``; with ``--workers N``, on a local Dask cluster, a worker's, and the
  workers of the two variants other than the command's run with Dask's own
  ``MALLOC_TRIM_THRESHOLD_=65536``); the reconstructions are compared too (keeping
  memory changes no number);
- ``chapter4.py`` as users run it (figures and report, 768 px) and with ``--dense
  --max-width 1536``, ``--full-runs`` times each: wall time and peak memory.
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
from collections.abc import Callable
from pathlib import Path

from bench_cli import REPO, add_data_arguments, data_folder, interleaved_times, plain_command

from scene3D.io.datasets import BOOK_PAIR
from scene3D.memory import MMAP_THRESHOLD_BYTES, user_tuned_malloc

CALIB = REPO / "data" / "fountain_P11_intrinsics.yaml"  # the Strecha scenes' camera
GLIBC_DEFAULTS = {"GLIBC_TUNABLES": "glibc.malloc.perturb=0"}
#: The heap glibc keeps by itself at most: twice its largest self-raised threshold.
GLIBC_CEILING_KEPT_BYTES = 2 * MMAP_THRESHOLD_BYTES


def variants(env: dict[str, str]) -> dict[str, dict[str, str]]:
    """The three environments compared: the command's own setting, 64 MiB kept (glibc's
    own ceilings, as a user's tunables) and glibc's defaults."""
    ceiling = {"GLIBC_TUNABLES": f"glibc.malloc.mmap_threshold={MMAP_THRESHOLD_BYTES}:"
                                 f"glibc.malloc.trim_threshold={GLIBC_CEILING_KEPT_BYTES}"}
    return {"as the command sets it (512 MiB kept)": env, "64 MiB kept": {**env, **ceiling},
            "glibc's defaults": {**env, **GLIBC_DEFAULTS}}


def user_environment() -> dict[str, str]:
    """The environment with bytecode written, as users run; it must hold no malloc setting."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    if user_tuned_malloc(env):
        raise SystemExit("error: unset your MALLOC_..._ variables and GLIBC_TUNABLES first: "
                         "this compares scene3D's malloc settings with glibc's defaults")
    return env


def run_measured(cmd: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Wall seconds of ``cmd`` and the peak resident MiB of its largest process, measured
    from a fresh child (``ru_maxrss`` of children is the largest so far, so each command
    gets its own)."""
    probe = [sys.executable, "-c",
             "import resource, subprocess, sys; subprocess.run(sys.argv[1:], check=True, "
             "capture_output=True); print(resource.getrusage(resource.RUSAGE_CHILDREN)."
             "ru_maxrss)", *cmd]
    t0 = time.perf_counter()
    proc = subprocess.run(probe, check=True, capture_output=True, text=True, env=env)
    return time.perf_counter() - t0, int(proc.stdout.split()[-1]) / 1024


def two_view_rows(data: Path, runs: int) -> list[str]:
    folder = data / "fountain-P11"
    env = user_environment()
    with tempfile.TemporaryDirectory() as out:
        ours = [sys.executable, str(REPO / "chapter4.py"),
                *(str(folder / name) for name in BOOK_PAIR), "--calib", str(CALIB),
                "--no-plots", "-q", "--out", out]
        commands = {"plain-OpenCV script": (plain_command(folder), env)}
        commands.update({f"chapter4.py --no-plots, {name}": (ours, variant_env)
                         for name, variant_env in variants(env).items()})
        times = interleaved_times(commands, runs)
    plain = times["plain-OpenCV script"]
    rows = ["| process | median s | fastest s | median / plain | fastest / plain |",
            "|---|---|---|---|---|"]
    for name, values in times.items():
        rows.append(f"| {name} | {statistics.median(values):.3f} | {min(values):.3f} | "
                    f"{statistics.median(values) / statistics.median(plain):.3f} | "
                    f"{min(values) / min(plain):.3f} |")
    return rows


def measure_variants(command: Callable[[str], list[str]], runs: int
                     ) -> tuple[dict[str, dict[str, list[float]]], bool]:
    """``runs`` interleaved runs of ``command(out_folder)`` in each of :func:`variants`:
    per variant the wall seconds, the features stage and the peak MiB of each run, and
    whether the variants' last reconstruction.json files differ beyond their timings."""
    env = user_environment()
    results = {v: {"wall": [], "features": [], "peak": []} for v in variants(env)}
    summaries = {}
    for _ in range(runs):
        for variant, variant_env in variants(env).items():
            with tempfile.TemporaryDirectory() as out:
                seconds, peak = run_measured(command(out), variant_env)
                summary = json.loads((Path(out) / "reconstruction.json").read_text())
            results[variant]["wall"].append(seconds)
            results[variant]["peak"].append(peak)
            results[variant]["features"].append(summary["timings_s"]["features"])
            summaries[variant] = json.dumps(
                {k: v for k, v in summary.items() if k not in ("timings_s", "files")},
                sort_keys=True)
    return results, len(set(summaries.values())) > 1


def _median_row(label: str, values: dict[str, list[float]], features: bool = True) -> str:
    return (f"| {label} | {statistics.median(values['wall']):.2f} | "
            + (f"{statistics.median(values['features']):.2f} | " if features else "")
            + f"{statistics.median(values['peak']):.0f} |")


def views_rows(data: Path, scenes: list[str], runs: int, workers: int | None) -> list[str]:
    rows = ["| scene | memory | wall s | features s | peak MiB |", "|---|---|---|---|---|"]
    for scene in scenes:
        results, differ = measure_variants(
            lambda out, scene=scene: [
                sys.executable, "-m", "scene3D", "reconstruct-views", str(data / scene / "images"),
                "--calib", str(CALIB), "--no-plots", "--no-report", "-q", "--out", out,
                *(["--workers", str(workers)] if workers else [])], runs)
        rows += [_median_row(f"{scene}{' (results differ!)' if differ else ''} | {variant}",
                             values) for variant, values in results.items()]
    return rows


def full_run_rows(data: Path, runs: int) -> list[str]:
    folder = data / "fountain-P11"
    runs_of = {"figures and report, 768 px": [], "--dense --max-width 1536": [
        "--dense", "--max-width", "1536"]}
    rows = ["| chapter4.py | memory | wall s | peak MiB |", "|---|---|---|---|"]
    for label, options in runs_of.items():
        results, _ = measure_variants(
            lambda out, options=options: [
                sys.executable, str(REPO / "chapter4.py"),
                *(str(folder / name) for name in BOOK_PAIR), "--calib", str(CALIB), *options,
                "-q", "--out", out], runs)
        rows += [_median_row(f"{label} | {variant}", values, features=False)
                 for variant, values in results.items()]
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_data_arguments(parser, scenes=True)
    parser.add_argument("--runs", type=int, default=21,
                        help="chapter4.py --no-plots runs of each variant (default: 21; 0 "
                             "skips them)")
    parser.add_argument("--views-runs", type=int, default=3,
                        help="reconstruct-views runs of each variant and scene (default: 3; "
                             "0 skips them)")
    parser.add_argument("--full-runs", type=int, default=3,
                        help="runs of each variant of chapter4.py with figures and report, "
                             "and with --dense (default: 3; 0 skips them)")
    parser.add_argument("--workers", type=int, default=None,
                        help="reconstruct-views on a local Dask cluster of N workers")
    args = parser.parse_args()
    data = data_folder(parser, args)
    if sys.platform != "linux":
        parser.error("glibc's malloc: Linux only")
    if args.runs:
        print(f"Two views, book pair at 768 px, whole processes ({args.runs} runs each, "
              "interleaved):\n")
        print("\n".join(two_view_rows(data, args.runs)))
    if args.views_runs:
        print(f"\nMany views at 1536 px, whole processes (median of {args.views_runs}, "
              f"interleaved{f', --workers {args.workers}' if args.workers else ''}):\n")
        print("\n".join(views_rows(data, args.scenes, args.views_runs, args.workers)))
    if args.full_runs:
        print(f"\nchapter4.py on the book pair (median of {args.full_runs}, interleaved):\n")
        print("\n".join(full_run_rows(data, args.full_runs)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
