"""``chapter4.py`` / ``scene3d reconstruct``: two photos in, plots, point cloud and summary out."""

from __future__ import annotations

import argparse
import logging
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..features.matching import FEATURE_MODES, normalize_feature_mode
from ..geometry.camera import adapt_intrinsics_to_size
from ..geometry.conventions import camera_centers, rotation_angle_deg
from ..io.calibration import load_calibration
from ..io.export import (
    all_or_nothing,
    atomic_write_bytes,
    atomic_write_pieces,
    write_json,
    write_ply,
)
from ..io.images import BOOK_MAX_WIDTH_PX, image_size, read_image_size
from ..scene import SceneReconstruction3D
from ..twoview import TwoViewSettings
from ..twoview.summary import pair_summary
from .common import (
    EXIT_OK,
    ArgumentParser,
    UsageError,
    add_bundle_adjust_arg,
    add_common_args,
    add_feature_arg,
    add_size_args,
    check_image_paths,
    check_report_viewer,
    exit_codes_help,
    focal_sigma_text,
    path_arg,
    read_camera_prior,
    run_command,
    show_images,
)
from .outputs import FILES_KEY, SUMMARY_FILE, OutputFolder, out_help

if TYPE_CHECKING:
    from ..geometry.intrinsics_prior import FocalPrior

logger = logging.getLogger("scene3D.cli")

REPO_DATA = Path(__file__).resolve().parents[2] / "data"
DEFAULT_CALIB = REPO_DATA / "fountain_P11_intrinsics.yaml"
PLOT_FILES = ("optic_flow.png", "epipolar_lines.png", "rectified.png", "point_cloud.png")
REPORT_FILE = "report.html"


def build_parser(prog: str = "chapter4.py") -> argparse.ArgumentParser:
    parser = ArgumentParser(
        prog=prog,
        description=(
            "Reconstruct a 3D scene from two photos of it taken by one calibrated camera "
            "(OpenCV with Python Blueprints, chapter 4). Without images it runs the book's "
            "example, fountain-P11 images 0004 and 0005 (found in $SCENE3D_DATA or the "
            "cache, or downloaded and checked)."
        ),
        epilog=(
            f"Outputs in --out: {', '.join(PLOT_FILES)}, point_cloud.ply (binary, RGB), "
            "cameras.json and colmap/ (a COLMAP text model of the two photos at their own "
            "size), "
            "with --dense dense.ply and disparity.png, and reconstruction.json (R, t with "
            "x_cam2 = R x_cam1 + t and |t| = 1: the scale is unknown), and report.html (one "
            "self-contained page: the numbers, the figures and an interactive 3D view of the "
            "cloud and the cameras; it opens offline). Files are replaced "
            "only once the run has succeeded. "
            + exit_codes_help(
                "the pair could not be reconstructed (the error says why: too few matches, a "
                "pure rotation, ...)",
                "success, also for a pose flagged as untrustworthy",
            ) + "."
        ),
    )
    parser.add_argument("images", nargs="*", metavar="IMAGE",
                        help="two photos of the same scene (default: the book's pair)")
    parser.add_argument("--calib", type=Path, metavar="FILE",
                        help="camera calibration (OpenCV YAML/XML as calibrate.py writes it); "
                             "scaled when the images have the same aspect ratio but another "
                             "size. Without it your own photos are self-calibrated: one focal "
                             "length, from EXIF (or 1.2 x the longer side) refined by the "
                             "photos, principal point at the centre, no distortion")
    add_feature_arg(parser, [m.lower() for m in FEATURE_MODES])
    add_size_args(parser, BOOK_MAX_WIDTH_PX, "the book's rule, 3072 -> 768")
    add_bundle_adjust_arg(parser)
    parser.add_argument("--dense", action="store_true",
                        help="also match every pixel of the rectified pair (SGBM) and write "
                             "dense.ply and disparity.png; a pair that cannot be rectified "
                             "into a disparity search (the camera moved towards the scene) "
                             "fails with exit code 1")
    parser.add_argument("--out", type=path_arg, default=Path("out"), metavar="DIR",
                        help=out_help("out/"))
    parser.add_argument("--no-plots", action="store_true",
                        help="skip the PNG figures")
    parser.add_argument("--no-report", action="store_true",
                        help=f"skip {REPORT_FILE}")
    parser.add_argument("--show", action="store_true",
                        help="also open the figures in windows when a display exists")
    add_common_args(parser)
    return parser


def _resolve_inputs(args: argparse.Namespace) -> tuple[Path, Path, Path | None]:
    """Image paths and calibration file, after the defaults (None: self-calibrate)."""
    if len(args.images) not in (0, 2):
        raise UsageError(f"give exactly two images (or none for the book's pair), got "
                         f"{len(args.images)}")
    if args.images:
        path1, path2 = Path(args.images[0]), Path(args.images[1])
        check_image_paths([path1, path2])
        return path1, path2, args.calib
    from ..io.datasets import BOOK_PAIR, fetch_fountain_p11  # the book's pair: its only use

    folder = fetch_fountain_p11(BOOK_PAIR)
    calib = args.calib if args.calib is not None else DEFAULT_CALIB
    return folder / BOOK_PAIR[0], folder / BOOK_PAIR[1], calib


class _Camera(NamedTuple):
    """The camera to start from: a calibration file's, or a prior to self-calibrate."""

    K: np.ndarray
    dist: np.ndarray
    image_size: tuple[int, int]
    prior: FocalPrior | None = None


def _load_camera(calib_path: Path | None, images: tuple[Path, Path]) -> _Camera:
    """The calibration file's camera, or without one the EXIF/default focal prior of
    ``images`` (:func:`scene3D.io.exif.read_camera_prior`: one camera is checked)."""
    if calib_path is None:
        prior = read_camera_prior(list(images))
        return _Camera(prior.K, np.zeros(5), prior.image_size, prior)
    if calib_path == DEFAULT_CALIB and not calib_path.is_file():
        # An installed copy without the repository's data/ folder: the same K from the dataset.
        from ..io.datasets import fetch_fountain_p11

        K = np.loadtxt(fetch_fountain_p11(("images/K.txt",)) / "images" / "K.txt")
        return _Camera(K, np.zeros(5), (3072, 2048))
    camera = load_calibration(calib_path)
    return _Camera(camera.K, camera.dist, camera.image_size)


def _self_calibrate(scene: SceneReconstruction3D, camera: _Camera, mode: str) -> list[str]:
    """Without a calibration file: the focal length from the photos (``scene.K`` changes).
    Returns the line to print about it (none with a calibration file)."""
    if camera.prior is None:
        return []
    calibration = scene.self_calibrate(mode, camera.prior.sigma_log, camera.prior.source)
    how = "refined by the photos" if calibration.determined else \
        "kept: the photos could not refine it"
    sigma = focal_sigma_text(calibration.focal_px, calibration.focal_sigma_px)
    return [f"focal length {calibration.focal_px:.1f} px {sigma} "
            f"at the working size ({camera.prior.description}; {how})"]


def _result_lines(scene: SceneReconstruction3D, result, paths: tuple[Path, Path],
                  dense) -> list[str]:
    """What the command prints about the result (also the head of the report)."""
    w, h = image_size(scene.img1)
    lines = [f"{paths[0].name} + {paths[1].name} at {w}x{h}, {result.feature}: "
             f"{result.num_matches} matches, {result.num_inliers} inliers, "
             f"{result.num_points} points, reprojection RMSE "
             f"{result.reprojection_rmse_px:.3f} px"]
    if dense is not None:
        lines.append(f"dense: {dense.num_points} points from disparities of "
                     f"{dense.disparity_range[0]} to {dense.disparity_range[1]} px (in size)")
    center = camera_centers(result.R[None], result.t[None])[0]  # camera 2 in camera 1's frame
    lines.append(f"camera 2: rotated {rotation_angle_deg(result.R):.2f} deg, centre at "
                 f"({center[0]:+.3f}, {center[1]:+.3f}, {center[2]:+.3f}) in camera 1's frame "
                 "(x right, y down, z forward; unit baseline)")
    if np.isfinite(result.rotation_sigma_deg) and np.isfinite(result.translation_sigma_deg):
        lines.append(f"pose uncertainty (1 sigma): rotation +-{result.rotation_sigma_deg:.3f} "
                     f"deg, translation direction +-{result.translation_sigma_deg:.3f} deg")
    return lines + warning_lines(result.trusted, result.warnings)


def warning_lines(trusted: bool, warnings: tuple[str, ...]) -> list[str]:
    """A result's warnings as printed: one line with the reasons when the pose is not
    trusted; one line each when they leave it trusted (a focal length the photos could
    not refine, kept from EXIF)."""
    if not trusted:
        return ["warning: the pose may not be trustworthy: " + "; ".join(warnings)]
    return [f"warning: {warning}" for warning in warnings]


def _figure_jobs(scene: SceneReconstruction3D, result, dense) -> dict[str, Callable]:
    """The figures to write, each a function drawing it with OpenCV (pure functions of the
    images and the result, so that they can run in threads; cv2 releases the GIL)."""
    from ..features.matching import find_matches
    from ..geometry.rectification import rectify_pair
    from ..viz.drawing import (
        draw_disparity,
        draw_epipolar_lines,
        draw_optic_flow,
        draw_rectified,
        frustum_corners,
        render_point_cloud,
        robust_extent,
    )

    img1, img2, K = scene.img1, scene.img2, scene.K

    def optic_flow():
        flow = find_matches(img1, img2, "flow")  # the book's figure tracks corners
        return draw_optic_flow(img1, flow.pts1, flow.pts2)

    def point_cloud():
        lo, hi = robust_extent(result.points3d)
        frusta = frustum_corners(np.stack([np.eye(3), result.R]),
                                 np.stack([np.zeros(3), result.t]), K, image_size(img1),
                                 0.08 * float(np.linalg.norm(hi - lo)))
        return render_point_cloud(result.points3d, result.colors, frusta, title=(
            f"Point cloud: {result.num_points} points, 2 cameras (red), unit baseline"))

    jobs = {
        "optic_flow.png": optic_flow,
        "epipolar_lines.png": lambda: draw_epipolar_lines(
            img1, img2, result.F, result.inlier_pts1, result.inlier_pts2),
        "rectified.png": lambda: draw_rectified(rectify_pair(img1, img2, K, result.R, result.t)),
        "point_cloud.png": point_cloud,
    }
    if dense is not None:
        jobs["disparity.png"] = lambda: draw_disparity(dense.disparity)
    return jobs


def _encode(job: Callable) -> tuple[bytes, bytes]:
    """A figure's PNG (the file) and JPEG (for the report) bytes."""
    from ..viz.drawing import encode_jpeg, encode_png, titled

    image = titled(job())
    # Quality 80 in the report: 30 % fewer bytes than 90, no loss visible at page size.
    return encode_png(image), encode_jpeg(image, quality=80)


def _figures_and_view(scene: SceneReconstruction3D, result, dense, plots: bool, report: bool
                      ) -> tuple[dict[str, tuple[bytes, bytes]], object]:
    """Figures encoded in two threads while this one prepares the report's 3D view."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=2) as pool:
        futures = {name: pool.submit(_encode, job)
                   for name, job in (_figure_jobs(scene, result, dense) if plots else {}).items()}
        view = None
        if report:
            from ..report import prepare_view, two_view_layers

            view = prepare_view(*two_view_layers(
                result.points3d, result.colors, result.R, result.t, scene.K,
                image_size(scene.img1), None if dense is None else dense.points3d,
                None if dense is None else dense.colors))
        return {name: future.result() for name, future in futures.items()}, view


#: The pair's model files beside point_cloud.ply (SceneReconstruction3D.save writes them).
MODEL_FILES = ("cameras.json", "colmap/cameras.txt", "colmap/images.txt", "colmap/points3D.txt")
#: Every file a run may write in ``--out``.
OUTPUT_NAMES = (*PLOT_FILES, "disparity.png", "point_cloud.ply", *MODEL_FILES, "dense.ply",
                SUMMARY_FILE, REPORT_FILE)


def _planned_outputs(args: argparse.Namespace) -> list[str]:
    """The names of the files a successful run writes in ``--out``."""
    figures = [] if args.no_plots else [*PLOT_FILES, *(["disparity.png"] if args.dense else [])]
    return [*figures, "point_cloud.ply", *MODEL_FILES, *(["dense.ply"] if args.dense else []),
            SUMMARY_FILE, *([] if args.no_report else [REPORT_FILE])]


def run(args: argparse.Namespace) -> int:
    t_start = time.perf_counter()
    mode = normalize_feature_mode(args.feature)
    path1, path2, calib_path = _resolve_inputs(args)
    camera = _load_camera(calib_path, (path1, path2))
    out_folder = OutputFolder(args.out, inputs=[path1, path2, *filter(None, [calib_path])],
                              names=OUTPUT_NAMES)
    out = out_folder.path
    out_folder.check_free(out / name for name in _planned_outputs(args))
    if not args.no_report:
        check_report_viewer()

    t0 = time.perf_counter()
    K = adapt_intrinsics_to_size(camera.K, camera.image_size, read_image_size(path1))
    scene = SceneReconstruction3D(K, camera.dist,
                                  TwoViewSettings(bundle_adjust=args.bundle_adjust))
    scene.load_image_pair(path1, path2, use_pyr_down=not args.no_pyr_down,
                          max_width=args.max_width)
    load_s = time.perf_counter() - t0

    calibration_lines = _self_calibrate(scene, camera, mode)
    result = scene.reconstruct(mode)
    timings = {"load": load_s, **{k: v for k, v in result.timings_s.items() if k != "total"}}

    dense = None
    if args.dense:
        t0 = time.perf_counter()
        dense = scene.dense_point_cloud(mode)
        timings["dense"] = time.perf_counter() - t0

    # Figures and report are made in memory first; files are written only once all is done.
    t0 = time.perf_counter()
    encoded, view = _figures_and_view(scene, result, dense, not args.no_plots,
                                      not args.no_report)
    timings["plots"] = time.perf_counter() - t0  # figures, and the 3D view's data alongside
    figures = {name: png for name, (png, _) in encoded.items()}

    def summarize(timings: dict[str, float]) -> dict:
        return pair_summary(result, (path1, path2), image_size(scene.img1), scene.native_size,
                            args.feature, timings, calib_path, scene.self_calibration,
                            camera.prior, dense)

    lines = _result_lines(scene, result, (path1, path2), dense)
    lines[1:1] = calibration_lines
    report = None
    if view is not None:
        from ..report import two_view_report

        t0 = time.perf_counter()
        partial = summarize(dict(timings))
        report = two_view_report(partial, lines, {n: jpg for n, (_, jpg) in encoded.items()},
                                 view)
        timings["report"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    with all_or_nothing():  # a write that fails leaves the previous run's files as they were
        written = [atomic_write_bytes(out / name, png) for name, png in figures.items()]
        written += scene.save(out, mode)  # point_cloud.ply, cameras.json, colmap/
        if dense is not None:
            written.append(write_ply(out / "dense.ply", dense.points3d, dense.colors))
        if report is not None:
            written.append(atomic_write_pieces(out / REPORT_FILE, report.encoded()))
        timings["write"] = time.perf_counter() - t0
        timings["total"] = time.perf_counter() - t_start
        summary = summarize(timings)
        summary[FILES_KEY] = out_folder.record([*written, out / SUMMARY_FILE])
        written.append(write_json(out / SUMMARY_FILE, summary))
    removed = out_folder.remove_stale(written)

    if not args.quiet:
        lines[0] += f", {timings['total']:.2f} s"
        print("\n".join(lines))
    for path in written:
        print(f"Wrote '{path}'")
    for path in removed:
        print(f"Removed '{path}' (an earlier run's, not written again)")
    if args.show and figures:
        show_images([out / name for name in figures])
    return EXIT_OK


def main(argv: list[str] | None = None, prog: str = "chapter4.py") -> int:
    """Entry point of ``chapter4.py``; returns the exit code."""
    args = build_parser(prog).parse_args(sys.argv[1:] if argv is None else argv)
    return run_command(args, run)
