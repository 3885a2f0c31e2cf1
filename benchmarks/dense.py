"""Speed and memory of the dense reconstruction on the book pair; its reach over scenes.

    python benchmarks/dense.py            # the book pair at 768 and 1536 px
    python benchmarks/dense.py --scenes   # every gap-1 and gap-2 pair of the shared scenes

Each size runs in its own process so that its peak memory (max RSS) is its own.
Prints a markdown table: working size, sparse and dense points, seconds for the
sparse pipeline and for the dense step, peak memory.

``--scenes`` (768 px, the Strecha cameras' K; data from ``SCENE3D_DATA``) prints, per
scene and gap: the pairs, those with a dense cloud, those refused (``ReconstructionError``)
or failing otherwise (any other exception), the median dense points, and how the dense
cloud agrees with the sparse one: per pair the median relative range difference at the
sparse points' rectified pixels (pairs with at least 10 such pixels), its median and
largest over the pairs.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time

import numpy as np

from scene3D.io.datasets import BOOK_PAIR, fetch_fountain_p11

SIZES = (768, 1536)


def measure(width: int) -> dict:
    from scene3D import SceneReconstruction3D
    from scene3D.io.datasets import read_strecha_camera

    folder = fetch_fountain_p11(BOOK_PAIR + ("gt_dense_cameras/0004.jpg.camera",))
    cam = read_strecha_camera(folder / "gt_dense_cameras" / "0004.jpg.camera")
    scene = SceneReconstruction3D(cam.K)
    scene.load_image_pair(folder / BOOK_PAIR[0], folder / BOOK_PAIR[1], max_width=width)
    t0 = time.perf_counter()
    sparse = scene.reconstruct()
    t1 = time.perf_counter()
    dense = scene.dense_point_cloud()
    t2 = time.perf_counter()
    return {"width": scene.img1.shape[1], "sparse_points": sparse.num_points,
            "dense_points": dense.num_points, "sparse_s": t1 - t0, "dense_s": t2 - t1,
            "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


SCENES = ("fountain-P11", "Herz-Jesus-P8", "castle-P19")


def agreement(scene, sparse, dense) -> float | None:
    """Median relative range difference, dense against sparse, at the sparse points'
    rectified pixels of image 1 (None with fewer than 10 such pixels)."""
    from scene3D.geometry.rectification import rectify_points

    rect = dense.rectified
    pixels = np.rint(rectify_points(sparse.pts1, scene.K, rect.R1, rect.P1)).astype(int)
    index = {(x, y): i for i, (x, y) in enumerate(dense.pixels.astype(int))}
    pairs = [(i, index[(x, y)]) for i, (x, y) in enumerate(pixels) if (x, y) in index]
    if len(pairs) < 10:
        return None
    s_idx, d_idx = np.array(pairs).T
    r_sparse = np.linalg.norm(sparse.points3d[s_idx], axis=1)
    r_dense = np.linalg.norm(dense.points3d[d_idx], axis=1)
    return float(np.median(np.abs(r_dense - r_sparse) / r_sparse))


def scenes_table() -> None:
    from scene3D import SceneReconstruction3D
    from scene3D.errors import ReconstructionError
    from scene3D.io.datasets import default_data_root, read_strecha_camera, strecha_views

    root = default_data_root()
    if root is None:
        sys.exit("error: set SCENE3D_DATA to the folder holding the Strecha scenes")
    print("| scene | gap | pairs | dense cloud | refused | failed | median points "
          "| agreement median / largest |")
    print("|---|---|---|---|---|---|---|---|")
    for name in SCENES:
        views = strecha_views(root / name)
        for gap in (1, 2):
            counts = {"ok": 0, "refused": 0, "failed": 0}
            points, agree = [], []
            for i in range(len(views) - gap):
                (a, camera_file), (b, _) = views[i], views[i + gap]
                camera = read_strecha_camera(camera_file)
                scene = SceneReconstruction3D(camera.K, camera.dist)
                scene.load_image_pair(a, b, max_width=768)
                try:
                    sparse = scene.reconstruct()
                    dense = scene.dense_point_cloud()
                except ReconstructionError:
                    counts["refused"] += 1
                    continue
                except Exception:  # noqa: BLE001 - what the table counts as failing
                    counts["failed"] += 1
                    continue
                counts["ok"] += 1
                points.append(dense.num_points)
                if (value := agreement(scene, sparse, dense)) is not None:
                    agree.append(value)
            agree_text = (f"{100 * np.median(agree):.2f} / {100 * max(agree):.2f} %"
                          if agree else "-")
            print(f"| {name} | {gap} | {len(views) - gap} | {counts['ok']} | "
                  f"{counts['refused']} | {counts['failed']} | "
                  f"{int(np.median(points)) if points else '-'} | {agree_text} |", flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--scenes", action="store_true",
                       help="every gap-1 and gap-2 pair of the shared scenes at 768 px "
                            "(data from SCENE3D_DATA) instead of the book pair's sizes")
    which.add_argument("--one", type=int, metavar="WIDTH",
                       help=argparse.SUPPRESS)  # one size in a process of its own, as JSON
    args = parser.parse_args(argv)
    if args.scenes:
        scenes_table()
        return 0
    if args.one is not None:
        print(json.dumps(measure(args.one)))
        return 0
    print("| width | sparse points | dense points | sparse s | dense s | peak memory MiB |")
    print("|---|---|---|---|---|---|")
    for width in SIZES:
        out = subprocess.run([sys.executable, __file__, "--one", str(width)], check=True,
                             capture_output=True, text=True).stdout
        r = json.loads(out)
        print(f"| {r['width']} | {r['sparse_points']} | {r['dense_points']} | "
              f"{r['sparse_s']:.2f} | {r['dense_s']:.2f} | {r['peak_mib']:.0f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
