"""Speed and memory of the dense reconstruction on the book pair.

    python benchmarks/dense.py

Each size runs in its own process so that its peak memory (max RSS) is its own.
Prints a markdown table: working size, sparse and dense points, seconds for the
sparse pipeline and for the dense step, peak memory.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import time

from scene3D.datasets import BOOK_PAIR, fetch_fountain_p11

SIZES = (768, 1536)


def measure(width: int) -> dict:
    from scene3D import SceneReconstruction3D
    from scene3D.datasets import read_strecha_camera

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


def main() -> int:
    if len(sys.argv) == 3 and sys.argv[1] == "--one":
        print(json.dumps(measure(int(sys.argv[2]))))
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
