"""``scene3d reconstruct-views``: cameras and points from many photos of one camera."""

from __future__ import annotations

import argparse
import glob
import logging
import sys
import time
from pathlib import Path

import numpy as np

from ..calibration_io import load_calibration
from ..camera import adapt_intrinsics_to_size
from ..datasets import read_strecha_camera
from ..evaluation import camera_set_error
from ..export import colmap_text_files, save_figure, write_json, write_ply, write_text_files
from ..features import FEATURE_MODES
from ..imageio import BOOK_MAX_WIDTH_PX, IMAGE_SUFFIXES, read_image_size
from ..multiview import SfMSettings, reconstruct_views
from .common import (
    EXIT_CODES_HELP,
    EXIT_OK,
    UsageError,
    add_common_args,
    add_feature_arg,
    add_size_args,
    check_distinct_images,
    check_report_viewer,
    positive_int,
    prepare_output_dir,
    run_command,
)

logger = logging.getLogger("scene3D.cli")


def build_parser(prog: str = "scene3d reconstruct-views") -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=prog,
        description=(
            "Incremental structure from motion: register many photos of one calibrated "
            "camera and triangulate their points, with bundle adjustment."
        ),
        epilog=(
            "Writes into --out: points.ply (binary, RGB), cameras.json (world-to-camera "
            "poses), colmap/cameras.txt, images.txt, points3D.txt (a COLMAP text model), "
            "reconstruction.json (summary), cameras.png (cloud with camera frusta) and "
            "report.html (the summary with an interactive 3D view; opens offline). "
            "Views that cannot be registered are named, not dropped silently. "
            f"{EXIT_CODES_HELP}."
        ),
    )
    parser.add_argument("images", nargs="+", metavar="IMAGES",
                        help="image files, a folder, or quoted globs such as 'photos/*.jpg'")
    parser.add_argument("--calib", type=Path, required=True, metavar="FILE",
                        help="camera calibration (OpenCV YAML/XML as calibrate.py writes it)")
    add_size_args(parser, 2 * BOOK_MAX_WIDTH_PX, "3072 -> 1536, half resolution")
    parser.add_argument("--pairs", choices=("auto", "all", "sequential"), default="auto",
                        help="which pairs to match: all pairs (up to 20 views in auto), or "
                             "each view with its --neighbours followers (ordered sequences)")
    parser.add_argument("--neighbours", type=positive_int, default=3, metavar="N",
                        help="with --pairs sequential (or auto beyond 20 views): how many "
                             "following views each view is matched with (default 3)")
    add_feature_arg(parser, [m.lower() for m in FEATURE_MODES if m != "flow"])
    parser.add_argument("--ground-truth", type=Path, metavar="DIR",
                        help="Strecha .camera files (NAME.camera per image): report camera "
                             "errors after a similarity alignment")
    parser.add_argument("--out", type=Path, default=Path("out/views"), metavar="DIR",
                        help="output folder (default out/views)")
    parser.add_argument("--no-plots", action="store_true", help="skip cameras.png")
    parser.add_argument("--no-report", action="store_true",
                        help="skip report.html (one self-contained page: the numbers, the "
                             "figure and an interactive 3D view of the points and cameras)")
    add_common_args(parser)
    return parser


def image_paths(specs: list[str]) -> list[Path]:
    """Files, folders (their images, sorted) and globs, in the order given."""
    paths: list[Path] = []
    for spec in specs:
        p = Path(spec)
        if p.is_dir():
            paths += sorted(q for q in p.iterdir() if q.suffix.lower() in IMAGE_SUFFIXES)
        elif p.is_file():
            paths.append(p)
        else:
            matched = sorted(Path(q) for q in glob.glob(spec) if Path(q).is_file())
            if not matched:
                raise FileNotFoundError(f"no image matches '{spec}'")
            paths += matched
    if len(paths) < 2:
        raise UsageError(f"need at least two images, got {len(paths)}")
    check_distinct_images(paths)
    return paths


def evaluate_against(folder: Path, names: list[str], recon) -> dict:
    """Camera errors of the registered views against Strecha ground truth."""
    reg = [i for i in range(len(names)) if recon.registered[i]]
    truth = [read_strecha_camera(folder / f"{names[i]}.camera") for i in reg]
    err = camera_set_error(recon.R[reg], recon.centers[reg], np.array([c.R for c in truth]),
                           np.array([c.center for c in truth]))
    return {
        "views": [names[i] for i in reg],
        "center_error_fraction_of_extent": err.center_errors,
        "rotation_error_deg": err.rotation_errors_deg,
        "max_center_error_fraction": float(err.center_errors.max()),
        "max_rotation_error_deg": float(err.rotation_errors_deg.max()),
    }


def _write_report(out: Path, names: list[str], recon, summary: dict, figure) -> Path:
    """report.html: the summary, cameras.png and the interactive 3D view (scene3D.report)."""
    from ..export import atomic_write_bytes
    from ..report import multi_view_layers, multi_view_report, prepare_view

    lines = [f"{summary['registered']} of {len(names)} views registered, "
             f"{summary['points']} points, mean track length {recon.mean_track_length:.2f}, "
             f"reprojection RMSE {recon.reprojection_rmse_px:.3f} px"]
    figures = {}
    if figure is not None:
        figures["cameras.png"] = (out / "cameras.png").read_bytes()
    view = prepare_view(*multi_view_layers(names, recon.K, recon.image_size, recon.registered,
                                           recon.R, recon.t, recon.points3d, recon.colors))
    page = multi_view_report(names, recon.registered, summary, lines, figures, view)
    return atomic_write_bytes(out / "report.html", page.encode("utf-8"))


def run(args: argparse.Namespace) -> int:
    t_start = time.perf_counter()
    paths = image_paths(args.images)
    camera = load_calibration(args.calib)
    out = prepare_output_dir(args.out)
    if args.ground_truth is not None and not args.ground_truth.is_dir():
        raise UsageError(f"--ground-truth '{args.ground_truth}' is not a folder")
    if not args.no_report:
        check_report_viewer()

    K_native = adapt_intrinsics_to_size(camera.K, camera.image_size, read_image_size(paths[0]))

    def progress(message: str) -> None:
        if not args.quiet:
            print(message, file=sys.stderr)

    names = [p.name for p in paths]
    recon = reconstruct_views(
        paths, K_native, camera.dist,
        max_width=None if args.no_pyr_down else args.max_width, names=names,
        feature=args.feature, pairs=args.pairs,
        settings=SfMSettings(neighbours=args.neighbours), progress=progress)
    timings = {k: v for k, v in recon.timings_s.items() if k != "total"}
    summary = {
        "views": len(names), "registered": int(recon.registered.sum()),
        "unregistered": list(recon.unregistered), "points": len(recon.points3d),
        "mean_track_length": recon.mean_track_length,
        "reprojection_rmse_px": recon.reprojection_rmse_px,
        "pair_selection": recon.pair_selection, "verified_pairs": recon.verified_pairs,
        "image_size": list(recon.image_size), "K": recon.K, "feature": args.feature,
        "conventions": "world = camera frame of the first view of the initial pair; "
                       "x_cam = R @ X + t; arbitrary scale",
    }
    if args.ground_truth is not None:
        summary["ground_truth"] = evaluate_against(args.ground_truth, names, recon)
    figure = None
    if not args.no_plots:
        from ..plotting import plot_cameras_and_points

        figure = plot_cameras_and_points(recon.points3d, recon.colors, recon.R, recon.t,
                                         recon.K, recon.image_size)
    obs = recon.observations
    colmap = colmap_text_files(names, recon.K, recon.image_size, recon.registered, recon.R,
                               recon.t, recon.points3d, recon.colors, obs.view, obs.point,
                               obs.xy, recon.point_errors_px())
    written = [write_ply(out / "points.ply", recon.points3d, recon.colors)]
    cameras = {n: {"R": recon.R[i], "t": recon.t[i], "center": recon.centers[i]}
               for i, n in enumerate(names) if recon.registered[i]}
    written.append(write_json(out / "cameras.json", cameras))
    written += write_text_files(out / "colmap", colmap)
    if figure is not None:
        written.append(save_figure(figure, out / "cameras.png"))
    timings["total"] = time.perf_counter() - t_start
    summary["timings_s"] = timings
    written.append(write_json(out / "reconstruction.json", summary))
    if not args.no_report:
        written.append(_write_report(out, names, recon, summary, figure))

    for name in recon.unregistered:
        logger.warning("view '%s' could not be registered", name)
    if not args.quiet:
        print(f"{summary['registered']} of {len(names)} views registered, "
              f"{summary['points']} points, mean track length "
              f"{recon.mean_track_length:.2f}, reprojection RMSE "
              f"{recon.reprojection_rmse_px:.3f} px, {timings['total']:.1f} s")
        if "ground_truth" in summary:
            gt = summary["ground_truth"]
            print(f"against ground truth: camera centres within "
                  f"{100 * gt['max_center_error_fraction']:.3f} % of the scene extent, "
                  f"rotations within {gt['max_rotation_error_deg']:.3f} deg")
    for path in written:
        print(f"Wrote '{path}'")
    return EXIT_OK


def main(argv: list[str] | None = None, prog: str = "scene3d reconstruct-views") -> int:
    args = build_parser(prog).parse_args(sys.argv[1:] if argv is None else argv)
    return run_command(args, run)
