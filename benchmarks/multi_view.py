"""Many views: accuracy, time per stage and memory, against plain OpenCV SIFT extraction.

    python benchmarks/multi_view.py [--scenes castle-P19 fountain-P11 Herz-Jesus-P8]
                                    [--orbit 50 100 200] [--no-shuffle] [--width 1536]
                                    [--one-thread]

Rows: each shared Strecha scene (``$SCENE3D_DATA``, default ../shared/data) under its own
file names and under random ones (symlinks in a temporary folder, shuffled order), and a
rendered orbit of 50, 100 and 200 views around a textured courtyard with known cameras
(``scene3D.evaluation.synthetic.orbit_scene``, 640x480, rendered once at 200 views; 100 and 50 take
every second and fourth). Each row runs in a fresh process, so that its peak memory
(max RSS) is its own, with default options (``--pairs auto``). In that process the plain
OpenCV SIFT extraction of the same images at the same size (``cv2.imread`` with the
reduced decoding that gives the working size, ``cv2.SIFT_create().detectAndCompute``) is
timed first, then ``reconstruct_views``; "x SIFT" is the second over the first, in wall
time and in CPU seconds of the process (all its threads). ``--one-thread`` runs every row
with one BLAS thread and one OpenCV thread (``OPENBLAS_NUM_THREADS=1``,
``cv2.setNumThreads(1)``): the CPU ratio then compares the algorithms' work, which the
load of a shared machine distorts less than wall time.

Errors: registered cameras aligned to the truth by a similarity
(``scene3D.evaluation.camera_set_error``), centres in % of the extent of the true
centres, rotations in degrees, max / median. The rotation of that alignment comes from
the camera orientations; the column "aligned by centres" repeats the errors with the
whole similarity fitted to the centres (``align="centres"``), the alignment of COLMAP's
model aligner and of the reference figures of issue #20 (see
``benchmarks/multi_view_colmap.py``). Prints a markdown table.
"""

from __future__ import annotations

import os

# The same BLAS setting as the command line (scene3D.cli): before numpy loads.
os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")

import argparse  # noqa: E402
import json  # noqa: E402
import random  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ORBIT_VIEWS = 200


def plain_sift_seconds(paths: list[Path], reduced: int) -> tuple[float, float]:
    """Plain OpenCV: read each image at the working size and extract its SIFT features.
    Returns the wall and the CPU seconds."""
    import cv2

    flag = {1: cv2.IMREAD_COLOR, 2: cv2.IMREAD_REDUCED_COLOR_2, 4: cv2.IMREAD_REDUCED_COLOR_4}
    t0, c0 = time.perf_counter(), time.process_time()
    for p in paths:
        img = cv2.imread(str(p), flag[reduced])
        cv2.SIFT_create().detectAndCompute(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), None)
    return time.perf_counter() - t0, time.process_time() - c0


def measure(spec: dict) -> dict:
    import cv2
    import numpy as np

    if spec.get("one_thread"):
        cv2.setNumThreads(1)

    from scene3D.evaluation import camera_set_error
    from scene3D.io.datasets import default_data_root, read_strecha_scene
    from scene3D.multiview import reconstruct_views

    if spec["kind"] == "orbit":
        from scene3D.evaluation.synthetic import asymmetric_camera, orbit_poses

        folder = Path(spec["folder"])
        step = ORBIT_VIEWS // spec["views"]
        paths = [folder / f"{k:03d}.png" for k in range(0, ORBIT_VIEWS, step)]
        K = asymmetric_camera(640, 480)
        Rs, ts = orbit_poses(ORBIT_VIEWS)
        R_true, t_true = Rs[::step], ts[::step]
        C_true = -np.einsum("vji,vj->vi", R_true, t_true)
        width, reduced = None, 1
    else:
        root = default_data_root() / spec["scene"]
        truth = read_strecha_scene(root)
        paths, R_true, C_true = truth.paths, truth.R, truth.centers
        K = np.loadtxt(root / "images" / "K.txt")
        width, reduced = spec["width"], 3072 // spec["width"]
        if spec.get("shuffle"):
            rng = random.Random(spec["seed"])
            order = list(range(len(paths)))
            rng.shuffle(order)
            tmp = Path(tempfile.mkdtemp())
            shuffled = []
            for k in order:
                link = tmp / f"{rng.randrange(10**8):08d}.jpg"
                link.symlink_to(paths[k])
                shuffled.append(link)
            paths, R_true, C_true = shuffled, R_true[order], C_true[order]
    plain, plain_cpu = plain_sift_seconds(paths, reduced)
    t0, c0 = time.perf_counter(), time.process_time()
    r = reconstruct_views(paths, K, np.zeros(5), max_width=width)
    total, total_cpu = time.perf_counter() - t0, time.process_time() - c0
    reg = np.flatnonzero(r.registered)
    err = camera_set_error(r.R[reg], r.centers[reg], R_true[reg], C_true[reg])
    by_centres = camera_set_error(r.R[reg], r.centers[reg], R_true[reg], C_true[reg],
                                  align="centres")
    timings = r.timings_s
    return {
        "views": len(paths), "registered": int(len(reg)), "models": len(r.models),
        "ok": r.ok, "points": len(r.points3d), "pairs": f"{r.verified_pairs}/{r.matched_pairs}",
        "selection": r.pair_selection.split(" (")[0],
        "center_max": 100 * float(err.center_errors.max()),
        "center_med": 100 * float(np.median(err.center_errors)),
        "rot_max": float(err.rotation_errors_deg.max()),
        "rot_med": float(np.median(err.rotation_errors_deg)),
        "by_centres": (f"{100 * by_centres.center_errors.max():.3f} / "
                       f"{100 * np.median(by_centres.center_errors):.3f} %, "
                       f"{by_centres.rotation_errors_deg.max():.3f} / "
                       f"{np.median(by_centres.rotation_errors_deg):.3f} deg"),
        "features": timings["features"], "retrieval": timings["retrieval"],
        "matching": timings["matching"],
        "mapping": timings["tracks"] + timings["initialisation"] + timings["registration"]
        + timings["checks"],
        "ba": timings["bundle_adjustment"], "total": total, "plain": plain,
        "total_cpu": total_cpu, "plain_cpu": plain_cpu,
        "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def render_orbit(folder: Path) -> None:
    import cv2

    from scene3D.evaluation.synthetic import (
        asymmetric_camera,
        orbit_poses,
        orbit_scene,
        render_planes,
    )

    K = asymmetric_camera(640, 480)
    scene = orbit_scene()
    for k, (R, t) in enumerate(zip(*orbit_poses(ORBIT_VIEWS))):
        img, _ = render_planes(K, R, t, rectangles=scene, supersample=1)
        cv2.imwrite(str(folder / f"{k:03d}.png"), img)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="*",
                        default=["castle-P19", "fountain-P11", "Herz-Jesus-P8"],
                        help="Strecha scenes under $SCENE3D_DATA (none: skip)")
    parser.add_argument("--orbit", type=int, nargs="*", default=[50, 100, 200],
                        help="synthetic orbit sizes, divisors of 200 (none: skip)")
    parser.add_argument("--no-shuffle", action="store_true",
                        help="skip the runs under shuffled file names")
    parser.add_argument("--width", type=int, default=1536, choices=(768, 1536, 3072),
                        help="working width of the Strecha images (default 1536)")
    parser.add_argument("--one-thread", action="store_true",
                        help="one BLAS and one OpenCV thread in every row (CPU comparison)")
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure(json.loads(args.one))))
        return 0
    load = os.getloadavg()[0]
    env = dict(os.environ)
    if args.one_thread:
        env["OPENBLAS_NUM_THREADS"] = "1"
    specs = []
    for scene in args.scenes:
        specs.append({"kind": "scene", "scene": scene, "width": args.width,
                      "label": scene})
        if not args.no_shuffle:
            specs.append({"kind": "scene", "scene": scene, "width": args.width,
                          "shuffle": True, "seed": 1, "label": f"{scene} shuffled"})
    with tempfile.TemporaryDirectory() as tmp:
        if args.orbit:
            t0 = time.perf_counter()
            render_orbit(Path(tmp))
            print(f"(orbit of {ORBIT_VIEWS} views rendered in {time.perf_counter() - t0:.0f} s)",
                  file=sys.stderr)
        for n in args.orbit:
            if ORBIT_VIEWS % n:
                parser.error(f"--orbit sizes must divide {ORBIT_VIEWS}, got {n}")
            specs.append({"kind": "orbit", "views": n, "folder": tmp, "label": f"orbit {n}"})
        print("| case | registered | models | check | pairs verified/matched | centre max / "
              "median (% extent) | rotation max / median (deg) | features s | retrieval s | "
              "matching s | mapping s | BA s | total s | plain SIFT s | x SIFT | total CPU s | "
              "plain SIFT CPU s | x SIFT (CPU) | peak MiB | aligned by centres |")
        print("|---" * 20 + "|")
        for spec in specs:
            spec["one_thread"] = args.one_thread
            out = subprocess.run([sys.executable, __file__, "--one", json.dumps(spec)],
                                 capture_output=True, text=True, env=env)
            if out.returncode:
                print(f"| {spec['label']} | failed: {out.stderr.strip().splitlines()[-1]} |")
                continue
            r = json.loads(out.stdout)
            print(f"| {spec['label']} | {r['registered']}/{r['views']} | {r['models']} | "
                  f"{'ok' if r['ok'] else 'FAILED'} | {r['pairs']} | "
                  f"{r['center_max']:.3f} / {r['center_med']:.3f} | "
                  f"{r['rot_max']:.3f} / {r['rot_med']:.3f} | {r['features']:.1f} | "
                  f"{r['retrieval']:.1f} | {r['matching']:.1f} | {r['mapping']:.1f} | "
                  f"{r['ba']:.1f} | {r['total']:.1f} | {r['plain']:.1f} | "
                  f"{r['total'] / r['plain']:.2f} | {r['total_cpu']:.1f} | "
                  f"{r['plain_cpu']:.1f} | {r['total_cpu'] / r['plain_cpu']:.2f} | "
                  f"{r['peak_mib']:.0f} | {r['by_centres']} |", flush=True)
    threads = "one BLAS and OpenCV thread" if args.one_thread else "default threads"
    print(f"(Strecha scenes at {args.width} px, default options, {threads}; "
          f"{time.strftime('%Y-%m-%d')}, load average {load:.1f} at the start, "
          f"{os.getloadavg()[0]:.1f} at the end)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
