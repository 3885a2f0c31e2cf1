"""reconstruct-views on 1 and 2 Dask worker processes, side by side.

    python benchmarks/cluster.py [--datasets fountain-P11 castle-P19] [--workers 1 2]
                                 [--repeats 3] [--max-width 2400] [--in-process]

Runs ``scene3D.multiview.reconstruct_views`` (what ``scene3d reconstruct-views``
runs, default pairs and size: 1536 px) with its tasks on N single-threaded worker
processes on 127.0.0.1, built as ``--workers N`` builds them
(:meth:`scene3D.engines.dask_engine.DaskEngine.local`), and reads the pipeline's own
stage timings: features (one task per image), retrieval (the vocabulary on the
client, one task per image for its words), matching (one task per pair, including the
pairs the mapper asks for later) and the rest (tracks, registration, triangulation,
bundle adjustment and checks: the sequential mapper, on the client). The clusters are
started (and warmed up) before timing; the configurations then alternate within every
repeat, so that each ratio compares runs made side by side under the same load. Every
run's cameras are checked to be identical to the first configuration's.

The machine's load average is printed before and after, with its ceiling: the CPU
that 2 busy processes get over what 1 gets (2.0 when two cores are free; near 1 when
the machine is busy and the kernel shares it out by session). Every row also gives
the CPU seconds of the worker processes over the wall time of the task stages ("cores
busy"), the workers' CPU seconds (the same work on 1 and 2 workers when nothing is
done twice) and those of the client with its scheduler (this process, mapper
included). On a shared machine the 1-vs-2-worker ratio measures the cores this run
got as much as the engine.

(Not named ``distributed.py``: run as a script, its folder comes first on
``sys.path`` and the file would shadow the ``distributed`` package.)
"""

from __future__ import annotations

import argparse
import logging
import os
import statistics
import sys
import time


def _cpu_seconds() -> float:
    """CPU time of this process so far (user + system)."""
    return time.process_time()


def _spin(seconds: float) -> float:
    """Pure CPU work for ``seconds`` of wall time; the CPU seconds it got."""
    start, cpu = time.perf_counter(), time.process_time()
    while time.perf_counter() - start < seconds:
        pass
    return time.process_time() - cpu


def cpu_ceiling(seconds: float = 3.0) -> float:
    """CPU that 2 busy processes get, over what 1 gets, now (2.0 on an idle machine).

    Every process of a session shares one scheduling group when the kernel groups
    by session (autogroup): on a busy machine, a second process then adds little.
    """
    import multiprocessing

    context = multiprocessing.get_context("spawn")
    got = {}
    for n in (1, 2):
        with context.Pool(n) as pool:
            got[n] = sum(pool.map(_spin, [seconds] * n))
    return got[2] / got[1]


def _warm_up() -> None:
    import cv2  # noqa: F401

    import scene3D.multiview  # noqa: F401


def cpu_seconds(engine) -> float:
    """CPU seconds used so far by the processes that run ``engine``'s tasks."""
    client = getattr(engine, "client", None)
    return sum(client.run(_cpu_seconds).values()) if client is not None else _cpu_seconds()


def run(engine, paths, cam, max_width):
    """reconstruct_views on ``engine``: its result, its timings and the CPU seconds of
    the workers and of this process."""
    from scene3D.multiview import reconstruct_views

    workers, here = cpu_seconds(engine), time.process_time()
    recon = reconstruct_views(paths, cam.K, cam.dist, max_width=max_width, engine=engine,
                              progress=lambda message: None)
    workers = cpu_seconds(engine) - workers
    here = time.process_time() - here
    return recon, recon.timings_s, workers, here


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--datasets", nargs="+", default=["fountain-P11", "castle-P19"])
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--threads", type=int, default=1,
                        help="threads per worker process (default 1)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--max-width", type=int, default=2400,
                        help="halve while wider (default 2400, reconstruct-views': 1536 px)")
    parser.add_argument("--in-process", action="store_true",
                        help="also time today's default, the in-process LocalEngine")
    args = parser.parse_args()

    import distributed  # noqa: F401  (configures its loggers; quietened next)
    import numpy as np

    logging.getLogger("distributed").setLevel(logging.WARNING)

    from scene3D.engines import LocalEngine
    from scene3D.engines.dask_engine import DaskEngine
    from scene3D.io.datasets import default_data_root, read_strecha_camera, strecha_views

    root = default_data_root()
    if root is None or not root.is_dir():
        print("error: set SCENE3D_DATA to the folder holding the datasets", file=sys.stderr)
        return 2
    ceiling = [cpu_ceiling()]
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())} "
          f"({os.cpu_count()} cores); CPU of 2 busy processes / 1: {ceiling[0]:.2f}",
          file=sys.stderr)

    engines, startup = {}, {}
    for n in args.workers:  # as --workers N builds them
        t0 = time.perf_counter()
        engine = DaskEngine.local(n, threads_per_worker=args.threads)
        engine.client.run(_warm_up)
        startup[n] = time.perf_counter() - t0
        engines[f"{n} worker{'s' * (n > 1)}"] = engine
    if args.in_process:
        engines["in-process"] = LocalEngine()

    datasets = {}
    for name in args.datasets:
        views = strecha_views(root / name)
        datasets[name] = ([image for image, _ in views], read_strecha_camera(views[0][1]))

    runs: dict[tuple[str, str], list[dict]] = {}
    first: dict[str, object] = {}
    facts: dict[str, tuple] = {}
    try:
        for rep in range(args.repeats):
            for name, (paths, cam) in datasets.items():
                for label, engine in engines.items():
                    recon, t, workers, here = run(engine, paths, cam, args.max_width)
                    if name in first:  # the same cameras, whichever engine
                        ref = first[name]
                        if not (np.array_equal(recon.R, ref.R, equal_nan=True)
                                and np.array_equal(recon.t, ref.t, equal_nan=True)):
                            raise AssertionError(f"{name}: {label} gave other cameras")
                    else:
                        first[name] = recon
                    facts[name] = (len(paths), recon.matched_pairs, int(recon.registered.sum()),
                                   recon.image_size[0])
                    tasks_s = t["features"] + t["retrieval"] + t["matching"]
                    row = {"features": t["features"], "retrieval": t["retrieval"],
                           "matching": t["matching"], "rest": t["total"] - tasks_s,
                           "total": t["total"], "parallel": t["features"] + t["matching"],
                           "cores": workers / tasks_s if label != "in-process" else 0.0,
                           "workers_cpu": workers if label != "in-process" else 0.0,
                           "client_cpu": here}
                    runs.setdefault((name, label), []).append(row)
                    print(f"repeat {rep + 1}, {name}, {label}: features {row['features']:.1f} s, "
                          f"retrieval {row['retrieval']:.1f} s, matching {row['matching']:.1f} "
                          f"s, rest {row['rest']:.1f} s; workers' CPU {workers:.1f} s, "
                          f"client's {here:.1f} s", file=sys.stderr)
    finally:
        for engine in engines.values():
            if isinstance(engine, DaskEngine):
                engine.close()
    ceiling.append(cpu_ceiling())
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"load average after: {load}; CPU of 2 busy processes / 1: {ceiling[1]:.2f}",
          file=sys.stderr)

    def median(name: str, label: str, key: str) -> float:
        return statistics.median(r[key] for r in runs[(name, label)])

    base = f"{args.workers[0]} worker{'s' * (args.workers[0] > 1)}"
    print("| dataset | views | pairs | engine | features s | retrieval s | matching s "
          "| features + matching s | rest (mapper) s | cores busy | workers' CPU s "
          f"| client CPU s | features + matching vs {base} (median) | per repeat |")
    print("|---" * 14 + "|")
    for name in datasets:
        views, pairs, _, _ = facts[name]
        reference = [r["parallel"] for r in runs[(name, base)]]
        for label in engines:
            ratios = [b / r["parallel"] for b, r in zip(reference, runs[(name, label)])]
            print(f"| {name} | {views} | {pairs} | {label} | "
                  + " | ".join(f"{median(name, label, k):.1f}" for k in
                               ("features", "retrieval", "matching", "parallel", "rest"))
                  + f" | {median(name, label, 'cores'):.2f} | "
                  f"{median(name, label, 'workers_cpu'):.1f} | "
                  f"{median(name, label, 'client_cpu'):.1f} | "
                  f"{statistics.median(ratios):.2f}x | "
                  f"{', '.join(f'{r:.2f}' for r in ratios)} |")
    widths = "/".join(sorted({str(f[3]) for f in facts.values()}))
    print(f"\nreconstruct-views at {widths} px, default pairs, {args.repeats} repeats; worker "
          f"processes with {args.threads} thread{'s' * (args.threads > 1)} each; cluster "
          "start-up and warm-up (not timed above): "
          + ", ".join(f"{n} worker{'s' * (n > 1)} {s:.1f} s" for n, s in startup.items()))
    print(f"The machine's ceiling (CPU that 2 busy processes got over 1, spinning 3 s each): "
          f"{ceiling[0]:.2f} before, {ceiling[1]:.2f} after; load average at the end {load} "
          f"on {os.cpu_count()} cores")
    top = f"{args.workers[-1]} worker{'s' * (args.workers[-1] > 1)}"
    for name in datasets:
        rest, total = median(name, top, "rest"), median(name, top, "total")
        print(f"{name}: {facts[name][2]} of {facts[name][0]} views registered; the sequential "
              f"mapper (on the client) took {rest:.1f} s of {total:.1f} s on {top} "
              f"({100 * rest / total:.0f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
