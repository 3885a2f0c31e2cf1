"""How multi-view reconstruction time and memory grow with the number of views.

    python benchmarks/multi_view.py [--width 1536] [--views 3 5 7 9 11]

Reconstructs the first N fountain-P11 images (all pairs matched) in a fresh process
per N, so that peak memory (max RSS) is its own, and prints a markdown table with
the stage times and the errors against the Strecha cameras.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time


def measure(n: int, width: int) -> dict:
    import numpy as np

    from scene3D.datasets import fetch_fountain_p11, read_strecha_camera
    from scene3D.evaluation import camera_set_error
    from scene3D.multiview import reconstruct_views

    folder = fetch_fountain_p11()
    cams = [read_strecha_camera(folder / "gt_dense_cameras" / f"{i:04d}.jpg.camera")
            for i in range(n)]
    t0 = time.perf_counter()
    r = reconstruct_views([folder / "images" / f"{i:04d}.jpg" for i in range(n)], cams[0].K,
                          max_width=width)
    total = time.perf_counter() - t0
    reg = np.nonzero(r.registered)[0]
    err = camera_set_error(r.R[reg], r.centers[reg], np.array([cams[i].R for i in reg]),
                           np.array([cams[i].center for i in reg]))
    return {"views": n, "width": r.image_size[0], "registered": int(len(reg)),
            "points": len(r.points3d), "rmse": r.reprojection_rmse_px, "total_s": total,
            **{f"{k}_s": v for k, v in r.timings_s.items() if k != "total"},
            "center_err_pct": 100 * float(err.center_errors.max()),
            "rot_err_deg": float(err.rotation_errors_deg.max()),
            "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--width", type=int, default=1536)
    parser.add_argument("--views", type=int, nargs="+", default=[3, 5, 7, 9, 11])
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure(args.one, args.width)))
        return 0
    print("| views | registered | points | RMSE px | load s | features s | matching s | BA s "
          "| total s | max centre err (% extent) | max rot err (deg) | peak MiB |")
    print("|---" * 12 + "|")
    for n in args.views:
        out = subprocess.run([sys.executable, __file__, "--one", str(n), "--width",
                              str(args.width)], check=True, capture_output=True, text=True)
        r = json.loads(out.stdout)
        print(f"| {n} | {r['registered']} | {r['points']} | {r['rmse']:.3f} | "
              f"{r['load_s']:.1f} | {r['features_s']:.1f} | {r['matching_s']:.1f} | "
              f"{r['bundle_adjustment_s']:.1f} | "
              f"{r['total_s']:.1f} | {r['center_err_pct']:.3f} | {r['rot_err_deg']:.3f} | "
              f"{r['peak_mib']:.0f} |")
    print(f"(fountain-P11 at {r['width']} px, all pairs matched)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
