"""``scene3d evaluate``: the two-view pipeline against a Strecha-format ground truth."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

import numpy as np

from ..errors import plural
from ..evaluation.pairs import (
    evaluate_pairs,
    focal_summary,
    pairs_from_specs,
    rows_csv_text,
    summarize_pair_rows,
    trust_line,
)
from ..features.matching import FEATURE_MODES, normalize_feature_mode
from ..io.datasets import read_strecha_camera, strecha_views
from ..io.export import atomic_write_bytes
from ..io.images import BOOK_MAX_WIDTH_PX
from ..twoview import TwoViewSettings
from .common import (
    EXIT_OK,
    ArgumentParser,
    UsageError,
    add_bundle_adjust_arg,
    add_common_args,
    add_engine_args,
    add_feature_arg,
    add_size_args,
    exit_codes_help,
    open_engine,
    path_arg,
    require_parent_folder,
    require_writable_folder,
    run_command,
)

logger = logging.getLogger(__name__)


def build_parser(prog: str = "scene3d evaluate") -> argparse.ArgumentParser:
    parser = ArgumentParser(
        prog=prog,
        description=(
            "Run the two-view reconstruction on image pairs of a dataset in the Strecha "
            "format (DATASET_DIR/images/NAME and DATASET_DIR/gt_dense_cameras/NAME.camera) "
            "and compare every relative pose with the ground truth."
        ),
        epilog=("Errors are in degrees: rotation angle of R_est R_true^T and the angle "
                "between translation directions; failed pairs count as infinite error. "
                "Sigmas are each pose's predicted 1-sigma rotation and translation-direction "
                "angles (worst axis); the summary says how often the errors fall within the "
                "predicted 90 % bounds (chi-square on the full covariance). "
                + exit_codes_help("the cluster gave a task up",
                                  "success (refused pairs are rows of the table)") + "."),
    )
    parser.add_argument("dataset", type=Path, metavar="DATASET_DIR",
                        help="a scene in the Strecha layout, such as fountain-P11")
    parser.add_argument("--pairs", nargs="+", default=["consecutive"], metavar="SPEC",
                        help="'consecutive' (i, i+1; default), 'skipN' (i, i+1+N: skip1 for "
                             "i, i+2, larger N for wider baselines), or explicit index pairs "
                             "such as 4-5 0-2 (indices into the sorted images)")
    add_size_args(parser, BOOK_MAX_WIDTH_PX, "the book's rule, 3072 -> 768")
    add_feature_arg(parser, [m.lower() for m in FEATURE_MODES])
    add_bundle_adjust_arg(parser)
    parser.add_argument("--no-calib", action="store_true",
                        help="ignore the camera files' intrinsics and distortion: each pair "
                             "starts from its photos' EXIF focal length (or 1.2 x the longer "
                             "side), principal point at the centre, and self-calibrates its "
                             "focal length, as chapter4.py does without --calib; the 'focal "
                             "fit' column is then the focal length found over the camera "
                             "file's, and the summary gives the median focal error")
    parser.add_argument("--csv", type=path_arg, metavar="FILE",
                        help="also write the per-pair rows (with notes) to this CSV file")
    parser.add_argument("--force", action="store_true",
                        help="overwrite an existing --csv file")
    add_engine_args(parser)
    add_common_args(parser, quiet_stdout="the result: the table, its summary lines and the "
                                         "CSV file written")
    return parser


def _views(dataset: Path) -> list[tuple[Path, Path]]:
    try:
        return strecha_views(dataset)
    except (FileNotFoundError, ValueError) as exc:
        raise UsageError(str(exc)) from None


def _check_csv_target(path: Path | None, force: bool) -> None:
    """Refuse, before any work, a --csv file that could not or should not be written
    (``-``, which elsewhere means stdout, too: the table is printed there)."""
    if path is None:
        return
    if str(path) == "-":
        raise UsageError("--csv '-': give a file name (the table is printed on stdout; "
                         "the CSV goes to a file)")
    if path.exists() and (path.is_dir() or not force):
        raise UsageError(f"--csv '{path}' exists; use --force to overwrite it"
                         if not path.is_dir() else f"--csv '{path}' is a folder")
    require_parent_folder(path, "--csv")
    require_writable_folder(path.parent, f"--csv '{path}' cannot be written: its folder "
                            f"'{path.parent}' refuses new files")


def run(args: argparse.Namespace) -> int:
    _check_csv_target(args.csv, args.force)
    views = _views(args.dataset)
    pairs = pairs_from_specs(args.pairs, len(views))  # ValueError: exit code 2
    cameras = [read_strecha_camera(cam) for _, cam in views]
    rows = []
    with open_engine(args) as engine:
        for row in evaluate_pairs(engine, [image for image, _ in views], cameras, pairs,
                                  None if args.no_pyr_down else args.max_width,
                                  normalize_feature_mode(args.feature),
                                  TwoViewSettings(bundle_adjust=args.bundle_adjust),
                                  no_calib=args.no_calib):
            rows.append(row)
            if not args.quiet:
                print(f"{row['pair']}: rot {row['rotation_deg']:.3f} deg, t-dir "
                      f"{row['translation_deg']:.3f} deg, {row['inliers']} inliers, "
                      f"{row['seconds']:.2f} s" + (f" {row['note']}" if row["note"] else ""),
                      file=sys.stderr)
    summary = summarize_pair_rows(rows)
    stats, calibration, fitted = summary["stats"], summary["calibration"], summary["focal_scales"]
    widths, feature = summary["widths"], summary["features"] or args.feature
    print("| pair | rotation err (deg) | t-dir err (deg) | rotation sigma (deg) | "
          "t-dir sigma (deg) | inliers | points | focal fit | trusted | s | note |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        focal = f"{r['focal_scale']:.3f}" if np.isfinite(r["focal_scale"]) else "-"
        sigmas = [f"{r[k]:.3f}" if np.isfinite(r[k]) else "-"
                  for k in ("rotation_sigma_deg", "translation_sigma_deg")]
        print(f"| {r['pair']} | {r['rotation_deg']:.3f} | {r['translation_deg']:.3f} | "
              f"{sigmas[0]} | {sigmas[1]} | {r['inliers']} | {r['points']} | {focal} | "
              f"{'no' if r['flagged'] else 'yes'} | {r['seconds']:.2f} | {r['note']} |")
    print(f"\n{plural(len(rows), 'pair')} at {widths} px, {feature}: median rotation "
          f"{stats['median_rotation_deg']:.3f} deg (p90 {stats['p90_rotation_deg']:.3f}), "
          f"median t-dir {stats['median_translation_deg']:.3f} deg "
          f"(p90 {stats['p90_translation_deg']:.3f}), both < 2 deg {stats['within_2deg']:.0%}, "
          f"< 5 deg {stats['within_5deg']:.0%}, AUC@5deg {stats['auc_5deg']:.1f}, "
          f"flagged {int(stats['flagged'])}, wrong and unflagged {int(stats['wrong_unflagged'])}"
          + (f"; the matches' focal length: median {float(np.median(fitted)):.3f} times the "
             "camera files'" if fitted else ""))
    print(trust_line(stats))
    if calibration["pairs"]:
        print(f"Sigma calibration: {calibration['rotation_within90']:.0%} of the rotation errors "
              f"and {calibration['translation_within90']:.0%} of the translation-direction "
              "errors within their predicted 90 % bounds "
              f"({plural(int(calibration['pairs']), 'pose')}; "
              "about 90 % when the sigmas are right, less when the camera files' own error "
              "is comparable to them)")
    if args.no_calib:
        print(focal_summary(rows))
    if args.csv is not None:
        atomic_write_bytes(args.csv, rows_csv_text(rows).encode())
        print(f"Wrote '{args.csv}'")
    return EXIT_OK


def main(argv: list[str] | None = None, prog: str = "scene3d evaluate") -> int:
    args = build_parser(prog).parse_args(sys.argv[1:] if argv is None else argv)
    return run_command(args, run)
