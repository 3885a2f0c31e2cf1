"""Features and matching on 1 and 2 Dask worker processes, side by side.

    python benchmarks/cluster.py [--datasets fountain-P11 castle-P19] [--workers 1 2]
                                 [--repeats 3] [--max-width 2400] [--in-process] [--no-mapper]

The stages of ``scene3d reconstruct-views`` that run as tasks: one task per image
(decoding at the working size, SIFT, colours: ``multiview.extract_features``) and
one per pair (ratio + mutual matching and the essential-matrix check:
``multiview.verify_pair``, all pairs as ``--pairs auto`` picks them up to 20 views),
through :class:`scene3D.engines.dask_engine.DaskEngine` on N single-threaded worker
processes on 127.0.0.1, built as ``--workers N`` builds them (``DaskEngine.local``).
The clusters are started (and warmed up) before timing; the configurations then
alternate within every repeat, so that each ratio compares runs made side by side under
the same load. Every run's verified matches are checked to be identical to the first
configuration's.

Last, the sequential rest of the pipeline (tracks, registration, triangulation and
bundle adjustment: ``multiview.incremental_reconstruction``, on the client) is timed
once per dataset, to give its share of the whole on 2 workers.

The machine's load average is printed before and after, with its ceiling: the CPU
that 2 busy processes get over what 1 gets (2.0 when two cores are free; near 1 when
the machine is busy and the kernel shares it out by session). Every row also says how
many cores its worker processes kept busy (their CPU seconds over the wall time), the
CPU seconds of the tasks (the same work on 1 and 2 workers, when nothing is done twice)
and of the client with its scheduler (this process). On a shared machine the
1-vs-2-worker ratio measures the cores this run got as much as the engine.

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
from pathlib import Path


def _view_features(path: Path, K, dist, max_width: int | None):
    """One image's task: its working image's SIFT features and colours."""
    from scene3D.imageio import load_working_image
    from scene3D.multiview import extract_features

    img, _, _ = load_working_image(path, K, dist, max_width)
    return extract_features(img)


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


def run_stages(engine, paths, K, dist, max_width, pairs, K_working, settings):
    """Features then pair verification on ``engine``: (features s, matching s, results)."""
    t0 = time.perf_counter()
    features = list(engine.map(_view_features, [(p, K, dist, max_width) for p in paths],
                               label="views"))
    t1 = time.perf_counter()
    from scene3D.multiview import verify_pair

    shared = [engine.share(f) for f in features]
    verified = list(engine.map(verify_pair, [(shared[i], shared[j], K_working, settings)
                                             for i, j in pairs], label="pairs"))
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1, features, verified


def _same(a: list, b: list) -> bool:
    import numpy as np

    return len(a) == len(b) and all(
        (x is None and y is None) or (x is not None and y is not None and
                                      all(np.array_equal(u, v) for u, v in zip(x, y)))
        for x, y in zip(a, b))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--datasets", nargs="+", default=["fountain-P11", "castle-P19"])
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--threads", type=int, default=1,
                        help="threads per worker process (default 1)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--max-width", type=int, default=2400,
                        help="halve while wider (default 2400, reconstruct-views': 1536 px)")
    parser.add_argument("--no-mapper", action="store_true",
                        help="skip timing the sequential mapper (minutes at 1536 px)")
    parser.add_argument("--in-process", action="store_true",
                        help="also time today's default, the in-process LocalEngine")
    args = parser.parse_args()

    import distributed  # noqa: F401  (configures its loggers; quietened next)

    logging.getLogger("distributed").setLevel(logging.WARNING)

    from scene3D.camera import scale_intrinsics_halved
    from scene3D.datasets import default_data_root, read_strecha_camera, strecha_views
    from scene3D.engines import LocalEngine
    from scene3D.engines.dask_engine import DaskEngine
    from scene3D.imageio import halving_levels, read_image_size
    from scene3D.multiview import SfMSettings, incremental_reconstruction, select_pairs

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
    settings = SfMSettings()
    for name in args.datasets:
        views = strecha_views(root / name)
        paths = [image for image, _ in views]
        cam = read_strecha_camera(views[0][1])
        levels = halving_levels(read_image_size(paths[0])[0], args.max_width)
        pairs, _ = select_pairs(len(paths))
        width = read_image_size(paths[0])[0] >> levels
        datasets[name] = (paths, cam, scale_intrinsics_halved(cam.K, levels), pairs, width)

    times: dict[tuple[str, str], list[tuple[float, float, float]]] = {}
    cpu_used: dict[tuple[str, str], list[tuple[float, float]]] = {}
    last: dict[str, tuple] = {}
    try:
        for rep in range(args.repeats):
            for name, (paths, cam, K_working, pairs, _) in datasets.items():
                for label, engine in engines.items():
                    cpu, here = cpu_seconds(engine), time.process_time()
                    feat_s, match_s, features, verified = run_stages(
                        engine, paths, cam.K, cam.dist, args.max_width, pairs, K_working,
                        settings)
                    work = cpu_seconds(engine) - cpu
                    cores = work / (feat_s + match_s)
                    client_cpu = time.process_time() - here if label != "in-process" else 0.0
                    if name in last and not _same(last[name][1], verified):
                        raise AssertionError(f"{name}: {label} verified other matches")
                    last[name] = (features, verified)
                    times.setdefault((name, label), []).append((feat_s, match_s, cores))
                    cpu_used.setdefault((name, label), []).append((work, client_cpu))
                    print(f"repeat {rep + 1}, {name}, {label}: features {feat_s:.1f} s, "
                          f"matching {match_s:.1f} s, {cores:.2f} cores busy, task CPU "
                          f"{work:.1f} s, client and scheduler CPU {client_cpu:.1f} s",
                          file=sys.stderr)
        mapper = {}
        for name, (_, _, K_working, pairs, _) in ([] if args.no_mapper else datasets.items()):
            features, verified = last[name]
            matches = {pair: v for pair, v in zip(pairs, verified) if v is not None}
            t0 = time.perf_counter()
            incremental_reconstruction(features, matches, K_working, settings)
            mapper[name] = time.perf_counter() - t0
            print(f"{name}: mapper {mapper[name]:.1f} s", file=sys.stderr)
    finally:
        for engine in engines.values():
            if isinstance(engine, DaskEngine):
                engine.close()
    ceiling.append(cpu_ceiling())
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"load average after: {load}; CPU of 2 busy processes / 1: {ceiling[1]:.2f}",
          file=sys.stderr)

    base = f"{args.workers[0]} worker{'s' * (args.workers[0] > 1)}"
    print("| dataset | views | pairs | engine | features s | matching s | features + matching s "
          f"| cores busy | task CPU s | client CPU s | speedup vs {base} (median) | per repeat |")
    print("|---" * 12 + "|")
    for name, (paths, _, _, pairs, _) in datasets.items():
        reference = [f + m for f, m, _ in times[(name, base)]]
        for label in engines:
            runs = times[(name, label)]
            totals = [f + m for f, m, _ in runs]
            ratios = [r / t for r, t in zip(reference, totals)]
            print(f"| {name} | {len(paths)} | {len(pairs)} | {label} | "
                  f"{statistics.median(f for f, _, _ in runs):.1f} | "
                  f"{statistics.median(m for _, m, _ in runs):.1f} | "
                  f"{statistics.median(totals):.1f} | "
                  f"{statistics.median(c for _, _, c in runs):.2f} | "
                  f"{statistics.median(w for w, _ in cpu_used[(name, label)]):.1f} | "
                  f"{statistics.median(c for _, c in cpu_used[(name, label)]):.1f} | "
                  f"{statistics.median(ratios):.2f}x | "
                  f"{', '.join(f'{r:.2f}' for r in ratios)} |")
    widths = "/".join(sorted({str(d[4]) for d in datasets.values()}))
    print(f"\nSIFT at {widths} px, all pairs, {args.repeats} repeats; worker processes with "
          f"{args.threads} thread{'s' * (args.threads > 1)} each; cluster start-up and "
          "warm-up (not timed above): " + ", ".join(f"{n} worker{'s' * (n > 1)} {s:.1f} s"
                                                    for n, s in startup.items()))
    print(f"The machine's ceiling (CPU that 2 busy processes got over 1, spinning 3 s each): "
          f"{ceiling[0]:.2f} before, {ceiling[1]:.2f} after; load average at the end {load} "
          f"on {os.cpu_count()} cores")
    top = f"{args.workers[-1]} worker{'s' * (args.workers[-1] > 1)}"
    for name in mapper:
        parallel = statistics.median(f + m for f, m, _ in times[(name, top)])
        share = 100 * mapper[name] / (mapper[name] + parallel)
        print(f"{name}: the sequential mapper (tracks, registration, bundle adjustment, on "
              f"the client) took {mapper[name]:.1f} s, {share:.0f} % of features + matching + "
              f"mapper on {top}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
