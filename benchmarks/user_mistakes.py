"""Two-view inputs a user could get wrong, through the book's class: does a wrong pose
come back trusted?

    python benchmarks/user_mistakes.py [--data DIR]

Each row is one pair of the shared scenes, changed as a user's mistake would change it:
a photo and a shifted copy of itself (no second view), image 2 at another zoom with one
calibration (a zoom lens), a principal point far from the centre, portrait photos with a
landscape calibration. Reconstructed at the default size (768 px) with the Strecha
camera's ``K`` (changed where the row says). Printed: what came back, the errors against
the true relative pose where there is one (rotation / translation direction, degrees),
the sigmas and the first warning or the refusal. A second table runs pairs whose photos
one camera matrix cannot describe (one zoomed, or both cropped off-centre) without a
calibration, self-calibrated from an EXIF focal length or the default prior, and gives the
focal length found against the truth. A trusted result more than 2 degrees off is the
failure this hunts for; a refusal or a flag is the right answer to most rows.
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np
from bench_cli import add_data_arguments, data_folder, reconstruct_or_refusal, verdict

from scene3D import SceneReconstruction3D
from scene3D.errors import ReconstructionError
from scene3D.evaluation import relative_pose_error
from scene3D.geometry.intrinsics_prior import ExifCamera, camera_prior
from scene3D.io.datasets import read_strecha_camera, relative_pose

#: cv2.ROTATE_90_CLOCKWISE as a rotation of the camera frame (x right, y down).
TURN_90 = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])


def zoomed(img: np.ndarray, factor: float, centre: tuple[float, float] | None = None
           ) -> np.ndarray:
    """``img`` as a camera with ``factor`` times the focal length, pointed the same way,
    would see it around ``centre`` (default: the image centre), at the same size."""
    h, w = img.shape[:2]
    cx, cy = centre or (w / 2, h / 2)
    A = np.array([[factor, 0, w / 2 - factor * cx], [0, factor, h / 2 - factor * cy]])
    return cv2.warpAffine(img, A, (w, h), flags=cv2.INTER_AREA if factor < 1 else
                          cv2.INTER_LINEAR)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_data_arguments(parser)
    data = data_folder(parser, parser.parse_args(argv))

    def camera(scene: str, i: int):
        return read_strecha_camera(data / scene / "gt_dense_cameras" / f"{i:04d}.jpg.camera")

    def image(scene: str, i: int) -> np.ndarray:
        return cv2.imread(str(data / scene / "images" / f"{i:04d}.jpg"))

    def pair(scene: str, i: int, j: int):
        return image(scene, i), image(scene, j), relative_pose(camera(scene, i), camera(scene, j))

    F, C, H = "fountain-P11", "castle-P19", "Herz-Jesus-P8"
    rows = []
    a = image(F, 4)
    shift = np.float32([[1, 0, 8], [0, 1, 0]])
    for feature in ("SIFT", "ORB"):
        rows.append((f"fountain 4 and itself shifted 8 px, {feature}", camera(F, 4).K, a,
                     cv2.warpAffine(a, shift, a.shape[1::-1]), None, feature))
    i4, i5, truth = pair(H, 4, 5)
    rows.append(("Herz-Jesus 4-5, image 2 zoomed 0.9x", camera(H, 4).K, i4, zoomed(i5, 0.9),
                 truth, "SIFT"))
    i5, i6, truth = pair(F, 5, 6)
    rows.append(("fountain 5-6, image 2 zoomed 0.85x", camera(F, 5).K, i5, zoomed(i6, 0.85),
                 truth, "SIFT"))
    i5, i6, truth = pair(C, 5, 6)
    rows.append(("castle 5-6, image 2 zoomed 1.5x at (922, 614)", camera(C, 5).K, i5,
                 zoomed(i6, 1.5, (922, 614)), truth, "SIFT"))
    i3, i4, truth = pair(H, 3, 4)
    corner = camera(H, 3).K.copy()
    corner[:2, 2] = 0.0
    rows.append(("Herz-Jesus 3-4, principal point (0, 0)", corner, i3, i4, truth, "SIFT"))
    i4, i5, truth = pair(F, 4, 5)
    moved = camera(F, 4).K.copy()
    moved[0, 2] += 0.1 * a.shape[1]
    rows.append(("fountain 4-5, principal point 10 % of the width off", moved, i4, i5, truth,
                 "SIFT"))
    i3, i4, (R, t) = pair(H, 3, 4)
    rows.append(("Herz-Jesus 3-4, both turned 90 deg, landscape K", camera(H, 3).K,
                 cv2.rotate(i3, cv2.ROTATE_90_CLOCKWISE), cv2.rotate(i4, cv2.ROTATE_90_CLOCKWISE),
                 (TURN_90 @ R @ TURN_90.T, TURN_90 @ t), "SIFT"))

    print("With the camera's calibration:\n")
    print("| case | result | error rot / t-dir (deg) | sigmas rot / t-dir (deg) | "
          "first warning or refusal |")
    print("|---|---|---|---|---|")
    for name, K, img1, img2, truth, feature in rows:
        scene = SceneReconstruction3D(K, np.zeros(5))
        scene.load_image_pair(img1, img2)
        _print_row(name, reconstruct_or_refusal(scene, feature), truth)

    # Without a calibration: the focal length from EXIF (32 mm, the camera's 35 mm
    # equivalent) or the default prior, self-calibrated by the pair.
    exif32 = ExifCamera(focal_length_35mm=32)
    uncalibrated = [
        ("fountain 4-5, image 2 zoomed 1.15x, no EXIF", F, 4, 5, None,
         lambda x: x, lambda x: zoomed(x, 1.15)),
        ("castle 4-5, image 2 zoomed 1.4x, EXIF 32 mm", C, 4, 5, exif32,
         lambda x: x, lambda x: zoomed(x, 1.4)),
        ("Herz-Jesus 3-4, both cropped to their top-left 2560x1706, no EXIF", H, 3, 4, None,
         lambda x: x[:1706, :2560], lambda x: x[:1706, :2560]),
        ("Herz-Jesus 3-4, cropped at (0, 0) and (512, 342), EXIF 32 mm", H, 3, 4, exif32,
         lambda x: x[:1706, :2560], lambda x: x[342:2048, 512:3072]),
    ]
    print("\nWithout a calibration (self-calibrated):\n")
    print("| case | result | error rot / t-dir (deg) | focal length found / true (px) | "
          "first warning or refusal |")
    print("|---|---|---|---|---|")
    for name, scene_name, i, j, exif, change1, change2 in uncalibrated:
        img1, img2, truth = pair(scene_name, i, j)
        img1, img2 = change1(img1), change2(img2)
        size = img1.shape[1::-1]
        prior = camera_prior([("a", exif, size), ("b", exif, size)])
        scene = SceneReconstruction3D(prior.K)
        scene.load_image_pair(img1, img2)
        try:
            calibration = scene.self_calibrate("SIFT", prior.sigma_log, prior.source)
        except ReconstructionError as exc:
            _print_row(name, exc, truth)
            continue
        true_px = camera(scene_name, i).K[0, 0] * scene.img1.shape[1] / size[0]
        _print_row(name, reconstruct_or_refusal(scene, "SIFT"), truth,
                   f"{calibration.focal_px:.0f} / {true_px:.0f}")
    return 0


def _print_row(name: str, outcome, truth, middle: str | None = None) -> None:
    """One table row: the verdict, the errors against ``truth`` (R, t) when there is one,
    ``middle`` (else the sigmas) and the first warning or the refusal."""
    if isinstance(outcome, ReconstructionError):
        print(f"| {name} | {verdict(outcome)} | | | {outcome.message[:110]} |")
        return
    error = "-"
    if truth is not None:
        e = relative_pose_error(outcome.R, outcome.t, *truth)
        error = f"{e.rotation_deg:.2f} / {e.translation_deg:.2f}"
    middle = middle or (f"{outcome.rotation_sigma_deg:.3f} / "
                        f"{outcome.translation_sigma_deg:.3f}")
    print(f"| {name} | {verdict(outcome)} | {error} | {middle} | "
          f"{(outcome.warnings or ('',))[0][:110]} |")


if __name__ == "__main__":
    raise SystemExit(main())
