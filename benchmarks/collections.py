"""Photo collections from other projects: scene3D and COLMAP with their defaults, side by side.

    python benchmarks/collections.py [FOLDER ...] [--no-colmap] [--threads 2] [--four-cameras]

Each FOLDER is a folder of photos (default: every folder in ``$SCENE3D_DATA/collections``,
``kermit`` and ``sceaux-castle``). Both run as a new user would, in a fresh process each,
one after the other on the same photos:

- scene3D: ``scene3d reconstruct-views FOLDER`` with its defaults (no ``--calib``);
- COLMAP (pycolmap, the bench extra): SIFT on the CPU, one SIMPLE_RADIAL camera per EXIF
  camera and size (``CameraMode.AUTO``), exhaustive matching, the incremental mapper,
  default options otherwise.

Per method: views registered in the largest model (and how many models), the focal length
at the photos' native size and the radial distortion k1 (both SIMPLE_RADIAL by default;
empty where a method found none), the focal length against the folder's ``K.txt`` where
there is one (the reference its project gives), the cameras of the largest model against COLMAP's
(``scene3D.evaluation.camera_set_error``, aligned by orientations: rotation max / median
in degrees, over the views both registered), and the wall time of the whole process, with
its ratio to COLMAP's. Prints a markdown table.

With ``--four-cameras``, also fountain-P11's photos made into four cameras
(:func:`scene3D.evaluation.camera_variants.write_camera_variants`: resized and cropped, no
EXIF), and a second table: each camera's focal length from each method against the truth
(the Strecha camera's, scaled), and the largest model's cameras against the Strecha ones.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
from scene3D.evaluation import camera_set_error  # noqa: E402
from scene3D.io.datasets import default_data_root  # noqa: E402

PHOTO_SUFFIXES = {".jpg", ".jpeg", ".png", ".tif", ".tiff", ".heic"}

#: The COLMAP run, in a child process so that its time and memory are its own. Prints one
#: JSON line: the largest model's views {name: [R, centre]}, its camera, the model count.
COLMAP_CHILD = r"""
import json, sys, time
from pathlib import Path
import pycolmap
images, work, threads = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
reader = pycolmap.ImageReaderOptions()
reader.camera_model = "SIMPLE_RADIAL"
extraction = pycolmap.FeatureExtractionOptions()
extraction.num_threads = threads
database = work / "database.db"
pycolmap.extract_features(database, images, camera_mode=pycolmap.CameraMode.AUTO,
                          reader_options=reader, extraction_options=extraction,
                          device=pycolmap.Device.cpu)
pycolmap.match_exhaustive(database, device=pycolmap.Device.cpu)
options = pycolmap.IncrementalPipelineOptions()
options.num_threads = threads
models = pycolmap.incremental_mapping(database, images, work / "sparse", options)
out = {"models": len(models), "views": {}, "cameras": []}
if models:
    rec = max(models.values(), key=lambda r: r.num_reg_images())
    for image in rec.images.values():
        if image.has_pose:
            pose = image.cam_from_world()
            R = pose.rotation.matrix()
            out["views"][Path(image.name).name] = [R.tolist(), (-R.T @ pose.translation).tolist()]
    out["cameras"] = [[c.model.name, list(c.params), c.width, c.height]
                      for c in rec.cameras.values()]
print(json.dumps(out))
"""


def photos(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.suffix.lower() in PHOTO_SUFFIXES)


def native_width(path: Path) -> int:
    from PIL import Image

    with Image.open(path) as img:
        return img.size[0]


def run_scene3d(folder: Path, work: Path) -> dict:
    """``scene3d reconstruct-views FOLDER`` with its defaults; the summary, cameras, time."""
    out = work / "scene3d"
    command = [sys.executable, "-m", "scene3D", "reconstruct-views", str(folder), "--out",
               str(out), "--no-plots", "--no-report", "-q"]
    t0 = time.perf_counter()
    proc = subprocess.run(command, capture_output=True, text=True, cwd=REPO)
    seconds = time.perf_counter() - t0
    if proc.returncode not in (0, 1) or not (out / "reconstruction.json").exists():
        return {"seconds": seconds, "error": proc.stderr.strip().splitlines()[-1:] or ["?"]}
    summary = json.loads((out / "reconstruction.json").read_text())
    cameras = json.loads((out / "cameras.json").read_text())
    scale = native_width(photos(folder)[0]) / summary["image_size"][0]
    largest = summary["models"][0] if summary.get("models") else {}
    return {"seconds": seconds, "models": len(summary.get("models", [])),
            "views": {name: [c["R"], c["center"]] for name, c in cameras.items()},
            "focal_px": summary["K"][0][0] * scale, "registered": largest.get("registered", 0),
            "k1": (summary.get("distortion") or [None])[0],
            "camera_model": summary.get("camera_model")}


def run_colmap(folder: Path, work: Path, threads: int) -> dict:
    t0 = time.perf_counter()
    command = [sys.executable, "-c", COLMAP_CHILD, str(folder), str(work), str(threads)]
    proc = subprocess.run(command, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    if proc.returncode != 0:
        return {"seconds": seconds, "error": proc.stderr.strip().splitlines()[-1:] or ["?"]}
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    result["seconds"] = seconds
    result["registered"] = len(result["views"])
    if result["cameras"]:
        name, params, width, _ = result["cameras"][0]
        result["focal_px"] = params[0] * native_width(photos(folder)[0]) / width
        result["k1"] = params[3] if name == "SIMPLE_RADIAL" else None
    return result


def camera_focals(method: str, r: dict, work: Path) -> dict[tuple[int, int], float]:
    """Each camera's focal length at its photos' size, by that size."""
    if "error" in r:
        return {}
    if method == "COLMAP":
        return {(w, h): params[0] for _, params, w, h in r["cameras"]}
    summary = json.loads((work / "scene3d" / "reconstruction.json").read_text())
    return {tuple(c["photo_size"]): c["focal_px_photo"] for c in summary["cameras"]}


def four_cameras(threads: int, no_colmap: bool) -> None:
    """The table of fountain-P11 as four cameras (the module docstring)."""
    from scene3D.evaluation.camera_variants import FOUR_CAMERAS, write_camera_variants
    from scene3D.io.datasets import read_strecha_scene

    root = default_data_root()
    scene = read_strecha_scene(root / "fountain-P11")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        folder = work / "fountain-4-cameras"
        factors = write_camera_variants(scene.paths, folder, FOUR_CAMERAS)
        sizes = [native_size(p) for p in photos(folder)]
        true_f = {size: scene.cameras[v].K[0, 0] * factors[v] for v, size in enumerate(sizes)}
        reference = {p.name: [c.R.tolist(), c.center.tolist()]
                     for p, c in zip(photos(folder), scene.cameras)}
        colmap = None if no_colmap else run_colmap(folder, work, threads)
        ours = run_scene3d(folder, work)
        print("\n| method | registered | focal error per camera (size: %) | rotations vs "
              "Strecha, max / median deg | wall s |")
        print("|---" * 5 + "|")
        for method, r in (("scene3D", ours), ("COLMAP", colmap)):
            if r is None:
                continue
            found = camera_focals(method, r, work)
            errors = ", ".join(f"{w}x{h}: {100 * (found[(w, h)] / f - 1):+.2f}"
                               if (w, h) in found else f"{w}x{h}: -"
                               for (w, h), f in sorted(true_f.items(), reverse=True))
            against = agreement(r.get("views", {}), reference)
            print(f"| {method} | {r.get('registered', 0)}/{len(sizes)} | {errors} | "
                  f"{against} | {r['seconds']:.1f} |", flush=True)


def native_size(path: Path) -> tuple[int, int]:
    from PIL import Image

    with Image.open(path) as img:
        return img.size


def agreement(views: dict, reference: dict) -> str:
    """Rotation max / median (deg) of ``views`` against ``reference`` over shared views."""
    shared = sorted(set(views) & set(reference))
    if len(shared) < 3:
        return "-"
    R = np.array([views[n][0] for n in shared])
    C = np.array([views[n][1] for n in shared])
    R_ref = np.array([reference[n][0] for n in shared])
    C_ref = np.array([reference[n][1] for n in shared])
    err = camera_set_error(R, C, R_ref, C_ref)
    return f"{err.rotation_errors_deg.max():.2f} / {np.median(err.rotation_errors_deg):.2f}"


def row(folder: Path, method: str, r: dict, colmap: dict | None) -> str:
    n = len(photos(folder))
    if "error" in r:
        return (f"| {folder.name} | {method} | 0/{n} | | | | | | {r['seconds']:.1f} | "
                f"{r['error'][0]} |")
    ref = folder / "K.txt"
    vs_k = ""
    if ref.exists() and r.get("focal_px"):
        vs_k = f"{100 * (r['focal_px'] / np.loadtxt(ref)[0, 0] - 1):+.1f} %"
    k1 = "" if r.get("k1") is None else f"{r['k1']:.3f}"
    ratio = "" if not colmap or "error" in colmap else f"{r['seconds'] / colmap['seconds']:.2f}"
    against = "" if method == "COLMAP" or not colmap or "error" in colmap else agreement(
        r["views"], colmap["views"])
    return (f"| {folder.name} | {method} | {r['registered']}/{n} | {r.get('models', '')} | "
            f"{r.get('focal_px', float('nan')):.1f} | {k1} | {vs_k} | {against} | "
            f"{r['seconds']:.1f} | {ratio} |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folders", nargs="*", type=Path,
                        help="folders of photos (default: $SCENE3D_DATA/collections/*)")
    parser.add_argument("--no-colmap", action="store_true", help="scene3D only")
    parser.add_argument("--threads", type=int, default=2, help="COLMAP's threads (default 2)")
    parser.add_argument("--four-cameras", action="store_true",
                        help="also fountain-P11's photos made into four cameras")
    args = parser.parse_args(argv)
    folders = args.folders
    if not folders:
        root = default_data_root()
        if root is None or not (root / "collections").is_dir():
            parser.error("no folders given and no $SCENE3D_DATA/collections")
        folders = sorted(p for p in (root / "collections").iterdir() if p.is_dir())
    print("| collection | method | registered | models | focal px (native) | k1 | vs K.txt "
          "| rotations vs COLMAP, max / median deg | wall s | x COLMAP |")
    print("|---" * 10 + "|")
    for folder in folders:
        with tempfile.TemporaryDirectory() as tmp:
            work = Path(tmp)
            colmap = None if args.no_colmap else run_colmap(folder, work, args.threads)
            ours = run_scene3d(folder, work)
            print(row(folder, "scene3D", ours, colmap), flush=True)
            if colmap is not None:
                print(row(folder, "COLMAP", colmap, None), flush=True)
    if args.four_cameras:
        four_cameras(args.threads, args.no_colmap)
    versions = ""
    if not args.no_colmap:
        import pycolmap

        versions = f"pycolmap {pycolmap.__version__}, "
    import cv2

    print(f"({versions}OpenCV {cv2.__version__}, {os.cpu_count()} cores; "
          f"{time.strftime('%Y-%m-%d')})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
