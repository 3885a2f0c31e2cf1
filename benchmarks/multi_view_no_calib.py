"""Many views without a calibration file against with one, on the shared Strecha scenes.

    python benchmarks/multi_view_no_calib.py [--scenes fountain-P11 Herz-Jesus-P8 castle-P19]
                                             [--width 1536] [--exif truth truthx0.7]

Each scene (``$SCENE3D_DATA``, default ../shared/data) is reconstructed twice with
``reconstruct_views`` at the same working size, each in a fresh process: with the camera
files' intrinsics (``K`` of the first view's ``.camera`` file, as ``--calib`` would give
it) and without any (``K=None``: the Strecha JPEGs carry no EXIF, so the focal length
starts from 1.2 times the longer side, 34 % long, and the photos refine it; the principal
point is the image centre). Registered views, the focal length found against the camera
files' (``sqrt(fx fy)`` at the working size) with the sigma the run gives, and the
registered cameras against the truth after a similarity alignment
(``scene3D.evaluation.camera_set_error``: centres in % of the extent of the true centres,
rotations in degrees, max / median). ``--exif SPEC ...`` adds a row per SPEC without a
calibration on copies of the JPEGs with an EXIF ``FocalLengthIn35mmFilm`` spliced in (the
pixels unchanged; SPEC as in ``benchmarks/self_calibration.py``: ``truth`` is the camera
files' focal length rounded to whole millimetres, ``truthx0.7`` 30 % short, as a
cropped copy would carry). Prints a markdown table.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def measure(scene: str, mode: str, width: int) -> dict:
    import numpy as np

    from scene3D.evaluation import camera_set_error
    from scene3D.io.datasets import default_data_root, read_strecha_scene
    from scene3D.multiview import reconstruct_views

    folder = default_data_root() / scene
    scene_truth = read_strecha_scene(folder)
    paths, truth = scene_truth.paths, scene_truth.cameras
    K = truth[0].K if mode == "calib" else None
    with tempfile.TemporaryDirectory(prefix="scene3d-exif-") as tmp:
        focal_35mm = None
        if mode not in ("calib", "none"):
            sys.path.insert(0, str(Path(__file__).parent))
            from self_calibration import exif_focal_35mm, with_exif

            focal_35mm = exif_focal_35mm(mode, folder)
            copies = [Path(tmp) / p.name for p in paths]
            for p, q in zip(paths, copies):
                q.write_bytes(with_exif(p.read_bytes(), focal_35mm))
            paths = copies
        t0 = time.perf_counter()
        recon = reconstruct_views(paths, K, max_width=width + 1, progress=lambda message: None)
        seconds = time.perf_counter() - t0
    reg = np.flatnonzero(recon.registered)
    err = camera_set_error(recon.R[reg], recon.centers[reg], np.array([truth[i].R for i in reg]),
                           np.array([truth[i].center for i in reg]))
    true_focal = math.sqrt(truth[0].K[0, 0] * truth[0].K[1, 1]) * recon.image_size[0] / \
        truth[0].image_size[0]
    focal = recon.focal
    return {
        "scene": scene, "calibration": recon.calibration_source, "exif_mm": focal_35mm,
        "registered": int(recon.registered.sum()), "views": len(paths),
        "models": len(recon.models), "ok": recon.ok,
        "focal_error": float(recon.K[0, 0] / true_focal - 1.0),
        "focal_sigma": None if focal is None else focal.sigma_px / focal.focal_px,
        "start_error": None if focal is None else focal.start_focal_px / true_focal - 1.0,
        "trusted": None if focal is None else focal.trusted,
        "center_max": 100 * float(err.center_errors.max()),
        "center_median": 100 * float(np.median(err.center_errors)),
        "rotation_max": float(err.rotation_errors_deg.max()),
        "rotation_median": float(np.median(err.rotation_errors_deg)),
        "rmse_px": recon.reprojection_rmse_px, "seconds": seconds,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="+",
                        default=["fountain-P11", "Herz-Jesus-P8", "castle-P19"])
    parser.add_argument("--width", type=int, default=1536,
                        help="working width: halve while wider (default 1536)")
    parser.add_argument("--exif", nargs="*", default=[], metavar="SPEC",
                        help="rows with an EXIF focal length spliced in: truth, truthxF, or mm")
    parser.add_argument("--calib-rows", choices=("yes", "no"), default="yes",
                        help="also the rows with the camera files and without EXIF (default yes)")
    parser.add_argument("--row", nargs=2, metavar=("SCENE", "MODE"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.row:
        print(json.dumps(measure(args.row[0], args.row[1], args.width)))
        return
    print("| scene | calibration | registered | focal error (start) | focal sigma | "
          "max / median centre error (%) | max / median rotation error (deg) | "
          "RMSE (px) | s |")
    print("|---|---|---|---|---|---|---|---|---|")
    modes = (["calib", "none"] if args.calib_rows == "yes" else []) + list(args.exif)
    for scene in args.scenes:
        for mode in modes:
            proc = subprocess.run([sys.executable, __file__, "--width", str(args.width),
                                   "--row", scene, mode], capture_output=True, text=True)
            if proc.returncode != 0:
                print(f"| {scene} | {mode} | failed: {proc.stderr.strip().splitlines()[-1]} |")
                continue
            r = json.loads(proc.stdout.strip().splitlines()[-1])
            focal = "-" if r["focal_sigma"] is None else (
                f"{100 * r['focal_error']:+.2f} % ({100 * r['start_error']:+.1f} %)")
            sigma = "-" if r["focal_sigma"] is None else f"{100 * r['focal_sigma']:.2f} %"
            label = "camera files" if mode == "calib" else r["calibration"]
            if r["exif_mm"] is not None:
                label = f"EXIF {r['exif_mm']} mm: {label}"
            if r["trusted"] is False:
                label += " (untrusted)"
            print(f"| {scene} | {label} | {r['registered']}/{r['views']}"
                  f"{'' if r['models'] == 1 else ' (' + str(r['models']) + ' models)'}"
                  f"{'' if r['ok'] else ', check failed'} | {focal} | {sigma} | "
                  f"{r['center_max']:.3f} / {r['center_median']:.3f} | "
                  f"{r['rotation_max']:.3f} / {r['rotation_median']:.3f} | "
                  f"{r['rmse_px']:.3f} | {r['seconds']:.0f} |", flush=True)


if __name__ == "__main__":
    main()
