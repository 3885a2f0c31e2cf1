"""Multi-view dense reconstruction (scene3D.densify): the plane sweep against rectified SGBM,
on a rendered orbit with exact geometry and on fountain-P11.

    python benchmarks/dense_views.py                    # synthetic + fountain-P11, both methods
    python benchmarks/dense_views.py --only synthetic   # or: --only fountain

Each row runs in its own process so that its peak memory (max RSS) is its own. Prints a
markdown table: scene, cameras, method, views, working width, fused points, seconds for
the depth maps (and per view) and for the fusion, peak memory, and on the rendered orbit
ETH3D's accuracy / completeness at 0.2 %, 0.5 % and 1 % of the scene's extent
(completeness of the surface at least three cameras see, and in brackets of all that any
camera sees). fountain-P11 (``SCENE3D_DATA``) runs with its Strecha cameras (the sparse
points of a reconstruct-views run moved into their frame by the similarity of the camera
centres) and with the cameras reconstruct-views estimated (``--sfm DIR``: a
reconstruct-views output folder; without it one is made in out/bench/dense_views/sfm).
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

OUT = Path("out/bench/dense_views")
TOLERANCES = (0.002, 0.005, 0.01)


def synthetic(method: str) -> dict:
    import cv2

    from scene3D.densify import DenseSettings, densify, image_paths, load_sparse_model
    from scene3D.evaluation.dense import render_orbit_views, score_dense_cloud
    from scene3D.io.colmap import colmap_model_from_views, write_colmap_text

    views, size = 8, (640, 480)
    scene = render_orbit_views(views, size=size, arc_deg=60.0)
    folder = OUT / "orbit"
    folder.mkdir(parents=True, exist_ok=True)
    names = [f"view{k:02d}.png" for k in range(views)]
    for name, img in zip(names, scene.images):
        cv2.imwrite(str(folder / name), img)
    write_colmap_text(folder / "model", colmap_model_from_views(
        names, scene.K, size, np.ones(views, bool), scene.R, scene.t, scene.sparse_points,
        np.full((len(scene.sparse_points), 3), 128, np.uint8), scene.obs_view,
        scene.obs_point, scene.obs_xy))
    model = load_sparse_model(folder / "model")
    result = densify(model, image_paths(model, folder),
                     DenseSettings(max_width=None, method=method))
    every = scene.surface_samples()
    extent = float(np.ptp(every, axis=0).max())
    tolerances = [f * extent for f in TOLERANCES]
    three = score_dense_cloud(result.cloud.points3d, scene.rectangles,
                              scene.surface_samples(min_views=3), tolerances)
    seen = score_dense_cloud(result.cloud.points3d, scene.rectangles, every, tolerances)
    row = _row("orbit (rendered)", "exact", method, result, size[0])
    row["scores"] = [f"{a.accuracy:.1%} / {a.completeness:.1%} ({b.completeness:.1%})"
                     for a, b in zip(three, seen)]
    return row


def _row(scene: str, cameras: str, method: str, result, width: int) -> dict:
    depth_s = result.timings_s["depth_maps"]
    views = sum(v is not None for v in result.previews)
    return {"scene": scene, "cameras": cameras, "method": method, "views": views,
            "width": width, "points": result.cloud.num_points, "depth_s": depth_s,
            "per_view_s": depth_s / max(views, 1),
            "fusion_s": result.timings_s["fusion"],
            "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def _sfm_folder(given: str | None) -> Path:
    if given:
        return Path(given)
    folder = OUT / "sfm"
    if not (folder / "colmap" / "points3D.txt").is_file():
        from scene3D.io.datasets import fetch_fountain_p11

        images = fetch_fountain_p11() / "images"
        subprocess.run([sys.executable, "-m", "scene3D", "reconstruct-views", str(images),
                        "--out", str(folder), "--no-report", "--no-plots", "-q"], check=True)
    return folder


def fountain(method: str, cameras: str, sfm: str | None) -> dict:
    from scene3D.densify import DenseSettings, densify, image_paths, load_sparse_model
    from scene3D.evaluation.poses import similarity_transform
    from scene3D.io.datasets import fetch_fountain_p11, read_strecha_camera

    root = fetch_fountain_p11()
    model = load_sparse_model(_sfm_folder(sfm))
    if cameras == "strecha":
        truth = [read_strecha_camera(root / "gt_dense_cameras" / f"{n}.camera")
                 for n in model.names]
        s, R, t = similarity_transform(model.centers, np.array([c.center for c in truth]))
        model = replace(model, R=np.array([c.R for c in truth]),
                        t=np.array([c.t for c in truth]),
                        points3d=s * model.points3d @ R.T + t)
    t0 = time.perf_counter()
    result = densify(model, image_paths(model, root / "images"), DenseSettings(method=method))
    width = next(v for v in result.previews if v is not None).image_size[0]
    row = _row("fountain-P11", cameras, method, result, width)
    row["total_s"] = time.perf_counter() - t0
    return row


def run_one(args: argparse.Namespace) -> None:
    scene, method, cameras = args.one
    row = synthetic(method) if scene == "synthetic" else fountain(method, cameras, args.sfm)
    print(json.dumps(row))


def main() -> None:
    parser = argparse.ArgumentParser(prog="dense_views.py", description=__doc__.split("\n")[0])
    parser.add_argument("--only", choices=("synthetic", "fountain"),
                        help="one of the two scenes")
    parser.add_argument("--methods", default="sweep,sgbm",
                        help="comma-separated depth methods (default sweep,sgbm)")
    parser.add_argument("--sfm", metavar="DIR", help="fountain-P11's reconstruct-views output")
    parser.add_argument("--one", nargs=3, metavar=("SCENE", "METHOD", "CAMERAS"),
                        help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        run_one(args)
        return
    runs = []
    for method in args.methods.split(","):
        if args.only in (None, "synthetic"):
            runs.append(("synthetic", method, "exact"))
        if args.only in (None, "fountain"):
            runs += [("fountain", method, "strecha"), ("fountain", method, "estimated")]
    rows = []
    for run in runs:
        extra = ["--sfm", args.sfm] if args.sfm else []
        proc = subprocess.run([sys.executable, __file__, "--one", *run, *extra],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            print(f"{run}: failed: {proc.stderr.strip().splitlines()[-1:]}", file=sys.stderr)
            continue
        rows.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    head = ["scene", "cameras", "method", "views", "width", "fused points", "depth maps s",
            "per view s", "fusion s", "peak MiB",
            *(f"acc / compl at {100 * f:g} %" for f in TOLERANCES)]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        scores = r.get("scores", ["-"] * len(TOLERANCES))
        print(f"| {r['scene']} | {r['cameras']} | {r['method']} | {r['views']} | {r['width']} | "
              f"{r['points']:,} | {r['depth_s']:.1f} | {r['per_view_s']:.1f} | "
              f"{r['fusion_s']:.1f} | {r['peak_mib']:.0f} | " + " | ".join(scores) + " |")
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "dense_views.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
