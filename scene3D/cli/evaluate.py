"""``scene3d evaluate``: the two-view pipeline against a Strecha-format ground truth."""

from __future__ import annotations

import argparse
import csv
import io
import logging
import math
import re
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..engines import Engine, Progress
from ..errors import ReconstructionError, plural
from ..evaluation.poses import relative_pose_error, sigma_calibration, summarize_pose_errors
from ..features.matching import (
    FEATURE_MODES,
    ImageFeatures,
    Matches,
    find_matches,
    image_features,
    match_features,
    normalize_feature_mode,
)
from ..geometry.camera import adapt_intrinsics_to_size, scale_intrinsics_halved
from ..io.datasets import StrechaCamera, read_strecha_camera, relative_pose, strecha_views
from ..io.export import atomic_write_bytes
from ..io.images import BOOK_MAX_WIDTH_PX, load_working_image, read_image_size
from ..optim.uncertainty import pose_error_chi2
from ..twoview import TwoViewSettings, check_against_flow, reconstruct_from_matches
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


def pairs_from_specs(specs: list[str], count: int) -> list[tuple[int, int]]:
    """The index pairs that ``specs`` select, in order; a pair selected twice (``4-5 4-5``,
    or ``consecutive 4-5``) is refused: it would count twice in the summary."""
    pairs: list[tuple[int, int]] = []
    given_by: dict[tuple[int, int], str] = {}
    for spec in specs:
        skip = re.fullmatch(r"skip(\d+)", spec)
        if spec == "consecutive" or skip:
            gap = 1 + (int(skip.group(1)) if skip else 0)
            selected = [(i, i + gap) for i in range(count - gap)]
        else:
            try:
                a, b = (int(v) for v in spec.split("-"))
            except ValueError:
                raise UsageError(f"bad pair {spec!r}: use consecutive, skipN or A-B") from None
            if not (0 <= a < count and 0 <= b < count):
                raise UsageError(f"pair {spec!r} is out of range 0..{count - 1}")
            if a == b:
                raise UsageError(f"pair {spec!r} pairs an image with itself")
            selected = [(a, b)]
        for pair in selected:
            if pair in given_by:
                by = f" (by {given_by[pair]!r} and {spec!r})" if given_by[pair] != spec else ""
                raise UsageError(f"pair {pair[0]}-{pair[1]} is given twice{by}: list each pair "
                                 "once (it would count twice in the summary)")
            given_by[pair] = spec
        pairs += selected
    if not pairs:
        raise UsageError(f"no image pairs: {' '.join(specs)} selects none of the {count} images")
    return pairs


@dataclass(frozen=True)
class _View:
    """What the pairs need of one view, computed once (one task per image).

    Attributes
    ----------
    shape : tuple[int, ...]
        ``(h, w, 3)`` of the working image.
    K : (3, 3) float64
        Intrinsics of the working image, from the view's camera file.
    features : ImageFeatures or None
        Keypoints and descriptors; None with ``--feature flow``.
    image : (h, w, 3) uint8
        The working image: the flow check of each pair's pose
        (:func:`scene3D.twoview.check_against_flow`) and ``--feature flow``'s tracks
        need it.
    photo : (name, ExifCamera or None, (width, height)) or None
        With ``--no-calib``: what :func:`scene3D.geometry.intrinsics_prior.camera_prior`
        needs of the photo (its EXIF and stored size).
    """

    shape: tuple[int, ...]
    K: np.ndarray
    features: ImageFeatures | None
    image: np.ndarray
    photo: tuple | None = None


def _load_view(path: Path, camera: StrechaCamera, max_width: int | None,
               feature: str, no_calib: bool = False) -> _View:
    """The working image of one view and its features (a task: see :func:`evaluate_pairs`).

    The camera file's ``K`` holds for its image size: a photo stored smaller (of the same
    aspect ratio) takes ``K`` scaled; another aspect ratio is an input error. With
    ``no_calib`` the camera file's distortion is not removed and the photo's EXIF and size
    are kept for the pair's focal-length prior.
    """
    size = read_image_size(path)
    try:
        K = adapt_intrinsics_to_size(camera.K, camera.image_size, size,
                                     what="its camera file")
    except ValueError as exc:
        raise ValueError(f"'{path}': {exc}") from None
    dist = camera.dist  # in normalised coordinates: the same at any size
    if no_calib:
        from ..io.exif import read_exif

        dist = np.zeros(5)
        photo = (path.name, read_exif(path), size)
    else:
        photo = None
    img, _, levels = load_working_image(path, K, dist, max_width)
    K_working = scale_intrinsics_halved(K, levels)
    if feature == "flow":
        return _View(img.shape, K_working, None, img, photo)
    return _View(img.shape, K_working, image_features(img, feature), img, photo)


def _matches(view_a: _View, view_b: _View) -> Matches:
    if view_a.features is None:  # flow: tracks belong to the pair
        return find_matches(view_a.image, view_b.image, "flow")
    return match_features(view_a.features, view_b.features)


def _unanswered_row(name: str, width: int) -> dict:
    """A row of the table before its pair is answered: what a refused pair keeps."""
    return {"pair": name, "width": width, "feature": "",
            "rotation_deg": np.inf, "translation_deg": np.inf, "inliers": 0, "points": 0,
            "rotation_sigma_deg": np.nan, "translation_sigma_deg": np.nan,
            "rotation_chi2": np.nan, "translation_chi2": np.nan,
            "focal_scale": np.nan, "behind_share": np.nan, "distortion_shift_deg": np.nan,
            "flagged": True, "note": ""}


def _evaluate_pair(name: str, view_a: _View, view_b: _View,
                   truth: tuple[np.ndarray, np.ndarray], settings: TwoViewSettings) -> dict:
    """One row of the table: the pose errors of a pair against the true relative pose
    ``truth`` = (R, t), or why it was refused (a task: see :func:`evaluate_pairs`)."""
    t0 = time.perf_counter()
    row = _unanswered_row(name, view_a.shape[1])
    try:
        if view_a.shape != view_b.shape or not np.allclose(view_a.K, view_b.K, rtol=1e-6,
                                                           atol=1e-6):
            row["note"] = "refused: the two views have different intrinsics or sizes " \
                          "(the two-view pipeline assumes one camera)"
            return row
        matches = _matches(view_a, view_b)
        row["feature"] = matches.feature
        try:
            result = reconstruct_from_matches(matches.pts1, matches.pts2, view_a.K, settings,
                                              K_source="camera files")
        except ReconstructionError as exc:
            row["note"] = f"refused: {exc.reason}"
            return row
        result = check_against_flow(result, view_a.image, view_b.image, settings)
        err = relative_pose_error(result.R, result.t, *truth)
        rotation_chi2, translation_chi2 = pose_error_chi2(result.R, result.t, *truth,
                                                          result.pose_covariance)
        row.update(rotation_deg=err.rotation_deg, translation_deg=err.translation_deg,
                   rotation_sigma_deg=result.rotation_sigma_deg,
                   translation_sigma_deg=result.translation_sigma_deg,
                   rotation_chi2=rotation_chi2, translation_chi2=translation_chi2,
                   inliers=result.num_inliers, points=len(result.points3d),
                   focal_scale=result.focal_scale, behind_share=result.behind_share,
                   distortion_shift_deg=result.distortion_pose_shift_deg,
                   flagged=not result.trusted,
                   note="; ".join(result.warnings))
        return row
    finally:  # the row's last column, whichever way it ends
        row["seconds"] = time.perf_counter() - t0


def _evaluate_pair_no_calib(name: str, view_a: _View, view_b: _View,
                            truth: tuple[np.ndarray, np.ndarray],
                            settings: TwoViewSettings) -> dict:
    """One row without the camera files' intrinsics: the pair self-calibrates its focal length
    from its photos' EXIF or the default prior (:mod:`scene3D.selfcalibration`), and
    ``focal_scale`` is the focal length found over the camera file's (a task: see
    :func:`evaluate_pairs`)."""
    from ..geometry.intrinsics_prior import CameraMismatchError, camera_prior
    from ..selfcalibration import self_calibrate_pair

    t0 = time.perf_counter()
    row = _unanswered_row(name, view_a.shape[1]) | {"focal_error": np.nan,
                                                    "calibration_source": ""}
    try:
        try:
            prior = camera_prior([view_a.photo, view_b.photo])
        except ValueError as exc:  # two sizes, cameras or zoom settings
            problem = exc.problem if isinstance(exc, CameraMismatchError) else exc
            row["note"] = f"refused: {problem}"  # without --no-calib, the camera files serve
            return row
        for message in prior.warnings:
            logger.warning("%s", message)
        levels = round(math.log2(prior.image_size[0] / view_a.shape[1]))
        matches = _matches(view_a, view_b)
        row["feature"] = matches.feature
        try:
            calibration = self_calibrate_pair(matches.pts1, matches.pts2,
                                              scale_intrinsics_halved(prior.K, levels),
                                              prior.sigma_log, prior.source, settings)
        except ReconstructionError as exc:
            row["note"] = f"refused: {exc.reason}"
            return row
        result = check_against_flow(calibration.geometry, view_a.image, view_b.image, settings)
        err = relative_pose_error(result.R, result.t, *truth)
        rotation_chi2, translation_chi2 = pose_error_chi2(result.R, result.t, *truth,
                                                          result.pose_covariance)
        scale = calibration.focal_px / math.sqrt(view_a.K[0, 0] * view_a.K[1, 1])
        row.update(rotation_sigma_deg=result.rotation_sigma_deg,
                   translation_sigma_deg=result.translation_sigma_deg,
                   rotation_chi2=rotation_chi2, translation_chi2=translation_chi2)
        row.update(rotation_deg=err.rotation_deg, translation_deg=err.translation_deg,
                   inliers=result.num_inliers, points=len(result.points3d), focal_scale=scale,
                   behind_share=result.behind_share,
                   distortion_shift_deg=result.distortion_pose_shift_deg,
                   flagged=not (result.trusted and calibration.focal_trusted),
                   focal_error=scale - 1.0,
                   calibration_source=calibration.source,
                   note="; ".join(calibration.warnings + result.warnings))
        return row
    finally:  # the row's last column, whichever way it ends
        row["seconds"] = time.perf_counter() - t0


def evaluate_pairs(engine: Engine, images: list[Path], cameras: list[StrechaCamera],
                   pairs: list[tuple[int, int]], max_width: int | None, feature: str,
                   settings: TwoViewSettings, progress: Progress | None = None,
                   no_calib: bool = False) -> Iterator[dict]:
    """The rows of the table, in the order of ``pairs``, computed by ``engine``.

    Each view used by a pair is one task (its working image and features), each
    pair another (matching, two-view reconstruction or self-calibration with
    ``no_calib``, errors against the truth); the pairs take their views as shared
    handles, so a view's features travel to a worker once, not with every pair.
    """
    used = sorted({i for pair in pairs for i in pair})
    views = engine.map(_load_view, [(images[i], cameras[i], max_width, feature, no_calib)
                                    for i in used],
                       label="views", progress=progress)
    shared = {i: engine.share(view) for i, view in zip(used, views)}
    rows = engine.map(_evaluate_pair_no_calib if no_calib else _evaluate_pair,
                      [(f"{images[a].name}-{images[b].name}", shared[a], shared[b],
                        relative_pose(cameras[a], cameras[b]), settings) for a, b in pairs],
                      label="pairs", progress=progress)
    del shared, views  # a view is kept (here or on the cluster) while a pair needs it
    yield from rows


def _focal_summary(rows: list[dict]) -> str:
    """The --no-calib summary line: focal errors against the camera files and their sources."""
    errors = np.abs([r["focal_error"] for r in rows if np.isfinite(r["focal_error"])])
    sources = {}
    for r in rows:
        if r["calibration_source"]:
            sources[r["calibration_source"]] = sources.get(r["calibration_source"], 0) + 1
    if not len(errors):
        return "without a calibration: no pair gave a focal length"
    return (f"without a calibration: focal length within {np.median(errors):.2%} of the camera "
            f"files' (median; p90 {np.percentile(errors, 90):.2%}, max {errors.max():.2%}) "
            f"on {plural(len(errors), 'pair')}; "
            + ", ".join(f"{n} {k}" for k, n in sorted(sources.items())))


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


def _csv_text(rows: list[dict]) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue()


def run(args: argparse.Namespace) -> int:
    _check_csv_target(args.csv, args.force)
    views = _views(args.dataset)
    pairs = pairs_from_specs(args.pairs, len(views))
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
    fitted = [r["focal_scale"] for r in rows if np.isfinite(r["focal_scale"])]
    stats = summarize_pose_errors([r["rotation_deg"] for r in rows],
                                  [r["translation_deg"] for r in rows],
                                  [r["flagged"] for r in rows])
    calibration = sigma_calibration([r["rotation_chi2"] for r in rows],
                                    [r["translation_chi2"] for r in rows])
    widths = "/".join(str(w) for w in sorted({r["width"] for r in rows}))
    # The detector that ran (SIFT when SURF is not in this OpenCV build).
    feature = "/".join(sorted({r["feature"] for r in rows if r["feature"]})) or args.feature
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
        print(_focal_summary(rows))
    if args.csv is not None:
        atomic_write_bytes(args.csv, _csv_text(rows).encode())
        print(f"Wrote '{args.csv}'")
    return EXIT_OK


def trust_line(stats: dict[str, float]) -> str:
    """The summary's line on the flags: right poses flagged, poses off and flagged."""
    return (f"Trust: {plural(int(stats['right_flagged']), 'right pose')} "
            f"(< 1 deg) flagged; {int(stats['off2_flagged'])} of "
            f"{plural(int(stats['off2']), 'pose')} "
            f"more than 2 deg off (or refused) flagged; {int(stats['wrong_unflagged'])} more "
            "than 5 deg off not flagged.")


def main(argv: list[str] | None = None, prog: str = "scene3d evaluate") -> int:
    args = build_parser(prog).parse_args(sys.argv[1:] if argv is None else argv)
    return run_command(args, run)
