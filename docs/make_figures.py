#!/usr/bin/env python
"""Make the documentation's figures in docs/images/ from the real data.

    python docs/make_figures.py [--only book|calibration|views]

Needs fountain-P11 and chessboard/opencv-left where the tests find them
(``$SCENE3D_DATA``, default ``../shared/data`` beside the checkout). The figures are
the library's own (``scene3D.viz.plotting``, the book's class), saved at a small size and
reduced to a 128-colour palette so that each stays well under 300 KB.

Written:

- ``book_pair.png``: the four plots of the book's pair in one picture (the README's);
- ``optic_flow.png``, ``epipolar_lines.png``, ``rectified.png``, ``point_cloud.png``,
  ``disparity.png``: the tutorial's figures of the same run;
- ``calibration_coverage.png``, ``calibration_view_errors.png``: OpenCV's left*.jpg;
- ``views_cameras.png``: all 11 fountain-P11 views with ``reconstruct_views``.
"""

from __future__ import annotations

import argparse
import io
import sys
from pathlib import Path

import cv2
import numpy as np
from PIL import Image  # Pillow comes with matplotlib

from scene3D import SceneReconstruction3D, reconstruct_views
from scene3D.calibration import BoardSpec, calibrate, corner_coverage, detect_board
from scene3D.io.calibration import load_calibration
from scene3D.io.datasets import BOOK_PAIR, default_data_root, fetch_fountain_p11
from scene3D.viz import plotting

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "docs" / "images"
MAX_BYTES = 300_000
COLOURS = 128


def _png(fig, width_px: int) -> Image.Image:
    """Render a matplotlib Figure and scale it to ``width_px`` wide (RGB)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100, bbox_inches="tight", facecolor="white")
    img = Image.open(buffer).convert("RGB")
    height = round(img.height * width_px / img.width)
    return img.resize((width_px, height), Image.LANCZOS)


def _save(img: Image.Image, name: str) -> None:
    path = OUT / name
    img.quantize(COLOURS, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)
    size = path.stat().st_size
    print(f"Wrote '{path.relative_to(REPO)}' ({img.width}x{img.height}, {size // 1000} KB)")
    if size > MAX_BYTES:
        sys.exit(f"error: '{path}' is {size} bytes, above {MAX_BYTES}")


def book_pair() -> None:
    fountain = fetch_fountain_p11()
    calib = load_calibration(REPO / "data" / "fountain_P11_intrinsics.yaml")
    scene = SceneReconstruction3D(calib.K, calib.dist)
    scene.load_image_pair(*(fountain / p for p in BOOK_PAIR))
    result = scene.reconstruct()
    dense = scene.dense_point_cloud()
    print(f"book pair: {result.num_inliers} inliers, {result.num_points} points, "
          f"{dense.num_points} dense points")
    figures = {
        "optic_flow.png": scene.plot_optic_flow(),
        "epipolar_lines.png": scene.draw_epipolar_lines(),
        "rectified.png": scene.plot_rectified_images(),
        "point_cloud.png": scene.plot_point_cloud(),
        "disparity.png": plotting.plot_disparity(dense.disparity),
    }
    images = {name: _png(fig, 720) for name, fig in figures.items()}
    for name, img in images.items():
        _save(img, name)

    # The README's picture: the book's four plots, two by two, 900 px wide.
    cell = 450
    tiles = [images[n].resize((cell, round(images[n].height * cell / images[n].width)),
                              Image.LANCZOS)
             for n in ("optic_flow.png", "point_cloud.png", "epipolar_lines.png",
                       "rectified.png")]
    top = max(tiles[0].height, tiles[1].height)
    bottom = max(tiles[2].height, tiles[3].height)
    sheet = Image.new("RGB", (2 * cell, top + bottom), "white")
    for k, tile in enumerate(tiles):
        row_y = 0 if k < 2 else top
        row_h = top if k < 2 else bottom
        sheet.paste(tile, ((k % 2) * cell, row_y + (row_h - tile.height) // 2))
    _save(sheet, "book_pair.png")


def calibration() -> None:
    root = default_data_root()
    if root is None:
        sys.exit("error: set SCENE3D_DATA to the folder holding chessboard/")
    board = BoardSpec()
    detections = []
    for path in sorted((root / "chessboard" / "opencv-left").glob("left*.jpg")):
        det = detect_board(cv2.imread(str(path), cv2.IMREAD_GRAYSCALE), board, path.name)
        if det is not None:
            detections.append(det)
    result = calibrate(detections, (640, 480), board)
    print(f"calibration: RMS {result.rms_px:.4f} px, fx {result.K[0, 0]:.2f}")
    points = [d.image_points for d in detections if d.name in result.per_view_errors_px]
    counts = corner_coverage(points, result.image_size)
    _save(_png(plotting.plot_calibration_coverage(points, result.image_size, counts), 640),
          "calibration_coverage.png")
    _save(_png(plotting.plot_view_errors(result.per_view_errors_px, result.rejected_views),
               640), "calibration_view_errors.png")


def views() -> None:
    fountain = fetch_fountain_p11()
    calib = load_calibration(REPO / "data" / "fountain_P11_intrinsics.yaml")
    paths = sorted((fountain / "images").glob("*.jpg"))
    recon = reconstruct_views(paths, calib.K, calib.dist)
    print(f"views: {int(np.sum(recon.registered))} of {len(paths)} registered, "
          f"{len(recon.points3d)} points")
    fig = plotting.plot_cameras_and_points(recon.points3d, recon.colors, recon.R, recon.t,
                                           recon.K, recon.image_size)
    _save(_png(fig, 700), "views_cameras.png")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=["book", "calibration", "views"],
                        help="make one group of figures (default: all)")
    args = parser.parse_args(argv)
    OUT.mkdir(parents=True, exist_ok=True)
    for name, make in (("book", book_pair), ("calibration", calibration), ("views", views)):
        if args.only in (None, name):
            make()
    return 0


if __name__ == "__main__":
    sys.exit(main())
