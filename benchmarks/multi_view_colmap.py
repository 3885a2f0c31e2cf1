"""COLMAP incremental (pycolmap) on the shared scenes, measured as ``multi_view.py`` measures.

    python benchmarks/multi_view_colmap.py [--scenes Herz-Jesus-P8 fountain-P11 castle-P19]
                                           [--width 1536] [--threads 2]

The reference of issue #20: the working images of ``reconstruct_views`` (the same
decoding, 1536 px by default) written as PNG, one PINHOLE camera with the known K scaled
to them, COLMAP's SIFT on the CPU, exhaustive matching, the incremental mapper with the
intrinsics fixed, default options otherwise. The largest model's cameras are compared
with the truth twice (``scene3D.evaluation.camera_set_error``): aligned with the rotation
from the camera orientations (``benchmarks/multi_view.py``'s errors) and with the whole
similarity fitted to the centres (``align="centres"``, COLMAP's model aligner). Centres
in % of the extent of the true centres, rotations in degrees, max / median; the wall time
of extraction, matching and mapping together. Prints a markdown table.

Needs the bench extra (pycolmap).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from scene3D.evaluation import camera_set_error  # noqa: E402
from scene3D.geometry.camera import scale_intrinsics_halved  # noqa: E402
from scene3D.io.datasets import default_data_root, read_strecha_scene  # noqa: E402
from scene3D.io.images import load_working_image  # noqa: E402


def errors(R, C, R_true, C_true, align: str) -> str:
    err = camera_set_error(R, C, R_true, C_true, align=align)
    return (f"{100 * err.center_errors.max():.3f} / {100 * np.median(err.center_errors):.3f} | "
            f"{err.rotation_errors_deg.max():.3f} / {np.median(err.rotation_errors_deg):.3f}")


def run(scene: str, width: int, threads: int, folder: Path) -> str:
    import pycolmap

    root = default_data_root() / scene
    truth = read_strecha_scene(root)
    paths, cams = truth.paths, truth.cameras
    K = np.loadtxt(root / "images" / "K.txt")
    images = folder / "images"
    images.mkdir()
    for p in paths:
        img, _, levels = load_working_image(p, K, np.zeros(5), width)
        cv2.imwrite(str(images / f"{p.stem}.png"), img)
    K_work = scale_intrinsics_halved(K, levels)
    # COLMAP puts pixel centres at +0.5 (scene3D.io.colmap.ColmapCamera.from_opencv).
    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "PINHOLE"
    reader.camera_params = (f"{K_work[0, 0]},{K_work[1, 1]},{K_work[0, 2] + 0.5},"
                            f"{K_work[1, 2] + 0.5}")
    extraction = pycolmap.FeatureExtractionOptions()
    extraction.num_threads = threads
    database = folder / "database.db"
    t0 = time.perf_counter()
    pycolmap.extract_features(database, images, camera_mode=pycolmap.CameraMode.SINGLE,
                              reader_options=reader, extraction_options=extraction,
                              device=pycolmap.Device.cpu)
    pycolmap.match_exhaustive(database, device=pycolmap.Device.cpu)
    options = pycolmap.IncrementalPipelineOptions()
    options.ba_refine_focal_length = False
    options.ba_refine_principal_point = False
    options.ba_refine_extra_params = False
    options.num_threads = threads
    models = pycolmap.incremental_mapping(database, images, folder / "sparse", options)
    seconds = time.perf_counter() - t0
    if not models:
        return f"| {scene} | no model | | | | | | |"
    rec = max(models.values(), key=lambda r: r.num_reg_images())
    stems = [p.stem for p in paths]
    R, C, R_true, C_true = [], [], [], []
    for image in rec.images.values():
        if not image.has_pose:
            continue
        k = stems.index(Path(image.name).stem)
        pose = image.cam_from_world()
        Rk = pose.rotation.matrix()
        R.append(Rk)
        C.append(-Rk.T @ pose.translation)
        R_true.append(cams[k].R)
        C_true.append(cams[k].center)
    R, C, R_true, C_true = map(np.array, (R, C, R_true, C_true))
    observations = sum(p.track.length() for p in rec.points3D.values())
    return (f"| {scene} | {len(R)}/{len(paths)} | {rec.num_points3D()} / {observations} | "
            f"{errors(R, C, R_true, C_true, 'orientations')} | "
            f"{errors(R, C, R_true, C_true, 'centres')} | {seconds:.0f} |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="+",
                        default=["Herz-Jesus-P8", "fountain-P11", "castle-P19"])
    parser.add_argument("--width", type=int, default=1536, choices=(768, 1536, 3072))
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    import pycolmap

    print("| scene | registered | points / observations | centre max / median (% extent), "
          "aligned by orientations | rotation max / median (deg) | centre max / median, "
          "aligned by centres | rotation max / median | wall s |")
    print("|---" * 8 + "|")
    for scene in args.scenes:
        with tempfile.TemporaryDirectory() as tmp:
            print(run(scene, args.width, args.threads, Path(tmp)), flush=True)
    print(f"(pycolmap {pycolmap.__version__}, {args.width} px, {args.threads} threads; "
          f"{time.strftime('%Y-%m-%d')})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
