"""``calibrate.py`` / ``scene3d calibrate``: calibrate a camera from photos, a video or a webcam."""

from __future__ import annotations

import argparse
import io
import json
import logging
import os
import sys
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from ..calibration.board import PATTERNS, BoardSpec, board_size_problem, min_image_side_px
from ..calibration.pipeline import calibrate_views
from ..calibration.solve import MAX_RMS_PX
from ..calibration.uncertainty import CORNER_LIMIT_PX
from ..calibration.views import (
    FRAMES,
    MIN_FRAMES,
    MIN_MOTION,
    VIDEO_SUFFIXES,  # noqa: F401 (the endings --images refuses; its old path)
    CollectedViews,
    ViewSourceError,
    photo_files,
    read_frames,
    read_photos,
)
from ..calibration.views import collect_views as collect_board_views
from ..errors import CalibrationError, plural
from ..geometry.camera import undistort_image
from ..io.calibration import CALIBRATION_SUFFIXES, save_calibration
from ..io.export import all_or_nothing, atomic_write_bytes, atomic_write_pieces
from ..io.images import IMAGE_SUFFIXES
from ..io.paths import lists_file
from .common import (
    EXIT_OK,
    ArgumentParser,
    UsageError,
    add_common_args,
    exit_codes_help,
    finite_non_negative_float,
    finite_positive_float,
    non_negative_int,
    path_arg,
    positive_float,
    require_parent_folder,
    require_writable_folder,
    run_command,
    show_images,
)
from .outputs import (
    FILES_KEY,
    previous_outputs,
    recorded_files,
    remove_earlier_files,
    remove_stale_outputs,
)

logger = logging.getLogger("scene3D.cli")


#: Defaults of the options that only a source or a pattern uses (None in the parser, so
#: that :func:`_ignored_options` can tell a value that was given); FRAMES, MIN_FRAMES and
#: MIN_MOTION are scene3D.calibration.views's.
DICTIONARY = "DICT_6X6_250"
#: The record of the undistorted copies a run wrote into --save-undistorted: a JSON object
#: naming the calibration (``UNDISTORTED_KEY``) and the copies (``FILES_KEY``), so that the
#: next run into that folder removes those it does not write again, and no file of the user's.
UNDISTORTED_RECORD = "undistorted.json"
UNDISTORTED_KEY = "undistorted_with"


def _board_size(text: str) -> tuple[int, int]:
    """argparse type: ``COLSxROWS``. The smallest size depends on ``--pattern``
    (:func:`~scene3D.calibration.board_size_problem`, checked once it is known)."""
    try:
        cols, rows = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"board size must look like 9x6, got {text!r}") from None
    return cols, rows


def build_parser(prog: str = "calibrate.py") -> argparse.ArgumentParser:
    parser = ArgumentParser(
        prog=prog,
        description=(
            "Calibrate a camera from views of a chessboard, a ChArUco board or a grid of "
            "circles and write its intrinsics for chapter4.py --calib. Headless unless --show."
        ),
        epilog=(
            "The output is OpenCV FileStorage YAML (camera_matrix, distortion_coefficients, "
            "image_width, image_height, rms_px, per_view_errors, view_names, std_intrinsics, "
            "projection_uncertainty_median_px, projection_uncertainty_worst_px, board, "
            "square_size_m, calibration_date); NAME_coverage.png, "
            "NAME_view_errors.png, NAME_uncertainty.png (the projection-uncertainty map) and "
            "NAME_report.html (one self-contained page with the numbers and the figures) are "
            "written beside it (NAME: --out without its suffix). "
            "Nothing is overwritten without --force. An --out with the NAME of another "
            "calibration file beside it (cam.json next to cam.yaml) is refused, --force or "
            "not, while that NAME's figures or report are there: they are the other file's. "
            + exit_codes_help("the calibration failed (it diverged, or its RMS error is "
                              "above --max-rms)") + "."
        ),
    )
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--images", metavar="GLOB_OR_DIR",
                        help="a folder of photos or a glob such as 'calib/*.jpg' (quote it)")
    source.add_argument("--video", type=Path, metavar="FILE", help="a video of the board")
    source.add_argument("--camera", type=non_negative_int, metavar="INDEX",
                        help="a webcam, e.g. 0")
    board = parser.add_argument_group("board")
    board.add_argument("--pattern", choices=PATTERNS, default="chessboard",
                       help="calibration target (default: chessboard): circles is a symmetric "
                            "grid of circles, acircles an asymmetric one (rows offset by half "
                            "a column, as OpenCV's acircles_pattern.png)")
    board.add_argument("--board", type=_board_size, default=None, metavar="COLSxROWS",
                       help="chessboard: inner corners, 3x3 or more (default 9x6, the "
                            "book's); "
                            "charuco: squares (default 5x7); circles, acircles: circles per "
                            "row x rows (acircles default 4x11, OpenCV's pattern; circles "
                            "has no default)")
    board.add_argument("--square-size", type=finite_positive_float, default=1.0, metavar="M",
                       help="side of a square in metres (circles: the distance between "
                            "neighbouring centres; acircles: between rows) (default 1.0, "
                            "i.e. results in those units; K and the distortion do not "
                            "depend on it)")
    board.add_argument("--marker-size", type=finite_positive_float, default=None, metavar="M",
                       help="charuco: side of a marker in metres, smaller than "
                            "--square-size (default: half a square)")
    board.add_argument("--dictionary", default=None,
                       help=f"charuco: ArUco dictionary (default {DICTIONARY})")
    parser.add_argument("--frames", type=int, default=None, metavar="N",
                        help=f"video/webcam: distinct views to collect, at least {MIN_FRAMES} "
                             f"(default {FRAMES}, the book's)")
    parser.add_argument("--min-motion", type=finite_non_negative_float, default=None,
                        metavar="FRACTION",
                        help="video/webcam: a view counts as distinct when its corners moved by "
                             f"this fraction of the image diagonal (default {MIN_MOTION:g})")
    parser.add_argument("--skip-other-sizes", action="store_true",
                        help="with photos of mixed sizes, keep the most common size and skip "
                             "the others (default: refuse)")
    parser.add_argument("--no-reject", action="store_true",
                        help="keep every view (default: drop views with > 3x the median error "
                             "and solve again)")
    parser.add_argument("--max-rms", type=positive_float, default=MAX_RMS_PX, metavar="PX",
                        help="refuse a calibration whose RMS reprojection error exceeds this "
                             f"(default {MAX_RMS_PX:g} px; a wrong --board gives far more)")
    parser.add_argument("--out", type=path_arg, default=Path("camera.yaml"), metavar="FILE",
                        help="output calibration: .yaml, .yml, .xml or .json "
                             "(default camera.yaml)")
    parser.add_argument("--force", action="store_true", help="overwrite existing outputs")
    parser.add_argument("--uncertainty-limit", type=positive_float, default=CORNER_LIMIT_PX,
                        metavar="PX",
                        help="warn when the projection uncertainty (1 sigma) at an image corner "
                             "or at the centre exceeds this (default "
                             f"{CORNER_LIMIT_PX:g} px)")
    parser.add_argument("--no-report", action="store_true",
                        help="skip NAME_report.html (with --force, an earlier run's is "
                             "removed: it would describe another calibration)")
    parser.add_argument("--save-undistorted", type=Path, metavar="DIR",
                        help="also write the undistorted views into DIR (NAME.png each, "
                             f"listed in DIR/{UNDISTORTED_RECORD}); a run with --force "
                             "replaces an earlier run's copies there and removes those it "
                             "does not write again (other files are kept); without --force "
                             "an earlier run's copies are refused")
    parser.add_argument("--show", action="store_true",
                        help="open the coverage and error plots in windows when a display exists")
    add_common_args(parser)
    return parser


def _board_from_args(args: argparse.Namespace) -> BoardSpec:
    if args.board is not None:
        problem = board_size_problem(args.pattern, args.board)
        if problem:
            raise UsageError(f"--board {args.board[0]}x{args.board[1]}: {problem}")
    if args.pattern == "chessboard":
        return BoardSpec("chessboard", args.board or (9, 6), args.square_size)
    if args.pattern == "acircles":
        return BoardSpec("acircles", args.board or (4, 11), args.square_size)
    if args.pattern == "circles":
        if args.board is None:
            raise UsageError("--pattern circles needs --board COLSxROWS (circles per row x "
                             "rows)")
        return BoardSpec("circles", args.board, args.square_size)
    marker = args.marker_size if args.marker_size is not None else args.square_size / 2
    if marker >= args.square_size:  # BoardSpec says so too, in its parameters' names
        raise UsageError(f"--marker-size {marker:g} must be smaller than --square-size "
                         f"{args.square_size:g}: a marker sits inside a square")
    return BoardSpec("charuco", args.board or (5, 7), args.square_size, marker,
                     args.dictionary or DICTIONARY)


def _ignored_options(args: argparse.Namespace) -> list[str]:
    """Warnings for the options given that the source or the pattern does not use (they
    are left out, as ``--show`` without a display is, rather than refused)."""
    notes = []
    if args.images is not None:
        notes += [f"{option} is for --video and --camera; ignored with --images"
                  for option, value in (("--frames", args.frames),
                                        ("--min-motion", args.min_motion))
                  if value is not None]
    elif args.skip_other_sizes:
        notes.append("--skip-other-sizes is for --images; ignored with "
                     + ("--video" if args.video is not None else "--camera"))
    if args.pattern != "charuco":
        notes += [f"{option} is for --pattern charuco; ignored with --pattern {args.pattern}"
                  for option, value in (("--marker-size", args.marker_size),
                                        ("--dictionary", args.dictionary))
                  if value is not None]
    return notes


def _with_flags(exc: ViewSourceError) -> UsageError:
    """The library's refusal of a source, as the command says it: with the flags."""
    source = exc.source
    if exc.reason == "video_not_photos":
        return UsageError(f"--images '{source}' is a video, not photos; use --video '{source}'")
    if exc.reason == "finds_video":
        return UsageError(f"--images '{source}' finds '{exc.details['video']}', a video, not a "
                          "photo: narrow the pattern to the photos (--video reads a video)")
    if exc.reason == "mixed_sizes":
        return UsageError(
            f"the images have different sizes: {exc.details['sizes']}; one calibration holds "
            "for one size (--skip-other-sizes keeps the most common)"
            + ("; some are stored turned by 90 degrees (their pixels are read as stored, "
               "whatever their EXIF orientation says)" if exc.details["turned"] else ""))
    if exc.reason == "folder_not_video":
        return UsageError(f"--video '{source}' is a folder, not a video file (--images takes "
                          "a folder of photos)")
    return UsageError(str(exc))


def _image_files(spec: str) -> list[Path]:
    """The photos ``--images`` names (:func:`scene3D.calibration.views.photo_files`)."""
    try:
        return photo_files(spec)
    except ViewSourceError as exc:
        raise _with_flags(exc) from None


def _source(args: argparse.Namespace) -> Iterator[tuple[str, np.ndarray]]:
    """The photos of ``--images`` or the frames of ``--video`` / ``--camera``."""
    if args.images is not None:
        return read_photos(_image_files(args.images), args.skip_other_sizes)
    return read_frames(args.video if args.video is not None else args.camera)


def with_stream_defaults(args: argparse.Namespace) -> argparse.Namespace:
    """A copy of ``args`` with ``--frames`` and ``--min-motion`` at their defaults when not
    given (the parser leaves them None, to tell a value given for photos, which is
    ignored with a warning, from the default)."""
    filled = argparse.Namespace(**vars(args))
    filled.frames = FRAMES if args.frames is None else args.frames
    filled.min_motion = MIN_MOTION if args.min_motion is None else args.min_motion
    return filled


def collect_views(args: argparse.Namespace, board: BoardSpec, keep_images: bool = False
                  ) -> CollectedViews:
    """The views of the command's source (:func:`scene3D.calibration.views.collect_views`),
    with its progress on stderr (not with ``-q``) and its warnings: a stream that ended
    before ``--frames`` views, photos without the board."""
    args = with_stream_defaults(args)
    from_stream = args.images is None

    def progress(message: str) -> None:
        if not args.quiet:  # -q: only errors on stderr
            print(message, file=sys.stderr)

    try:
        found = collect_board_views(_source(args), board,
                                    frames=args.frames if from_stream else None,
                                    min_motion=args.min_motion, keep_images=keep_images,
                                    progress=progress)
    except ViewSourceError as exc:
        raise _with_flags(exc) from None
    if len(found.views) >= 3:  # fewer is an error that gives the counts
        if found.ended_early:
            logger.warning("the %s ended after %d frames with %d of the %d distinct views "
                           "asked for (--frames); calibrating on those", _stream_kind(args),
                           found.seen, len(found.views), args.frames)
        elif not from_stream and found.without_board:
            logger.warning("the board was not found in %d of the %d photos, left out: %s",
                           len(found.without_board), found.seen,
                           ", ".join(found.without_board))
    return found


def _stream_kind(args: argparse.Namespace) -> str:
    return "video" if args.video is not None else "camera stream"


def _png(fig) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100, bbox_inches="tight")
    return buffer.getvalue()


def _report_path(args: argparse.Namespace) -> Path:
    """``NAME_report.html`` beside ``--out``."""
    return Path(f"{args.out.with_suffix('')}_report.html")


def _figure_paths(args: argparse.Namespace) -> list[Path]:
    """``NAME_coverage.png``, ``NAME_view_errors.png``, ``NAME_uncertainty.png``."""
    stem = args.out.with_suffix("")
    return [Path(f"{stem}_{name}.png") for name in ("coverage", "view_errors", "uncertainty")]


def _outputs(args: argparse.Namespace) -> list[Path]:
    """The calibration, its three figures and (unless --no-report) its report."""
    return [args.out, *_figure_paths(args), *([] if args.no_report else [_report_path(args)])]


def _same_name_calibration(args: argparse.Namespace) -> str:
    """Why ``--out`` cannot share its NAME with another calibration file beside it
    (``cam.json`` next to ``cam.yaml``), or '': the figures and the report are named after
    NAME alone, so those already there (the other file's) would be replaced by this
    calibration's and describe it, not the file they were written with. Refused whatever
    ``--force`` says: it allows replacing ``--out``'s own outputs, not another file's."""
    out = args.out
    named = [p for p in (*_figure_paths(args), _report_path(args)) if p.is_file()]
    if not named or not out.parent.is_dir():
        return ""
    others = sorted(p for p in out.parent.iterdir()
                    if p.stem == out.stem and p.suffix.lower() in CALIBRATION_SUFFIXES
                    and p.is_file() and not (out.exists() and p.samefile(out)))
    if not others:
        return ""
    return (f"--out '{out}' has the NAME of '{others[0]}' beside it, whose figures and "
            f"report ('{named[0]}', ...) are named after NAME only: this calibration's would "
            f"replace them; name --out otherwise (such as "
            f"'{out.with_name(f'{out.stem}-2{out.suffix}')}'), or remove '{others[0]}' and "
            "its files first")


def _not_written_again(args: argparse.Namespace) -> list[Path]:
    """The files of the same NAME an earlier run wrote that this one does not write
    (its report, after ``--no-report``): they would describe another calibration than
    the new ``--out``, so a run with ``--force`` removes them (without, it refuses)."""
    report = _report_path(args)
    return [report] if args.no_report and report.is_file() else []


def _earlier_copies(args: argparse.Namespace) -> list[Path]:
    """The undistorted copies an earlier run recorded in ``--save-undistorted``'s
    :data:`UNDISTORTED_RECORD` (none without one); :class:`UsageError` when a file of that
    name there is not such a record (it would be replaced)."""
    target = args.save_undistorted
    if target is None or not target.is_dir():
        return []
    return previous_outputs(target, UNDISTORTED_RECORD, UNDISTORTED_KEY, "--save-undistorted")


def _check_outputs(args: argparse.Namespace, outputs: list[Path]) -> None:
    """Refuse, before any work, outputs that could not be written or would overwrite files."""
    out = args.out
    if out.is_dir():
        raise UsageError(f"--out '{out}' is a folder; name a file in it, such as "
                         f"'{out / 'camera.yaml'}'")
    if out.suffix.lower() not in CALIBRATION_SUFFIXES:
        raise UsageError(f"--out must end in {', '.join(CALIBRATION_SUFFIXES[:-1])} or "
                         f"{CALIBRATION_SUFFIXES[-1]}, got '{out}'")
    folders = [p for p in outputs if p.is_dir()]
    if folders:
        raise UsageError(f"'{folders[0]}' is a folder; it stands where an output goes")
    shared = _same_name_calibration(args)
    if shared:
        raise UsageError(shared)
    existing = [p for p in outputs if p.exists()]
    if existing and not args.force:
        raise UsageError(f"'{existing[0]}' exists; use --force to overwrite it")
    earlier = _not_written_again(args)
    if earlier and not args.force:
        raise UsageError(f"'{earlier[0]}' exists (an earlier run's) and would describe "
                         "another calibration than the new one; use --force to remove it")
    require_parent_folder(out, "--out")
    require_writable_folder(out.parent, f"--out '{out}': cannot write in '{out.parent}'")
    if args.images is not None:
        read_back = [p.name for p in outputs if lists_file(args.images, p)]
        if read_back:
            raise UsageError(f"--out '{out}' puts {', '.join(read_back)} where --images "
                             "finds the photos: the next run would take them for photos; "
                             "write --out in another folder")
    target = args.save_undistorted
    if target is not None:
        if target.exists() and not target.is_dir():
            raise UsageError(f"--save-undistorted '{target}' is a file, not a folder")
        existing_folder = next(p for p in (target, *target.parents) if p.exists())
        if not existing_folder.is_dir():
            raise UsageError(f"--save-undistorted '{target}': '{existing_folder}' is a file, "
                             "not a folder")
        require_writable_folder(existing_folder, f"--save-undistorted '{target}': cannot "
                                f"write in '{existing_folder}'")
        if (target / UNDISTORTED_RECORD).resolve() == out.resolve():
            raise UsageError(f"--out '{out}' is where --save-undistorted '{target}' lists its "
                             "copies; name --out otherwise")
        earlier = [p for p in _earlier_copies(args) if p.is_file()]
        if (earlier or (target / UNDISTORTED_RECORD).is_file()) and not args.force:
            raise UsageError(f"--save-undistorted '{target}' holds the undistorted copies of "
                             f"an earlier run (as its {UNDISTORTED_RECORD} lists them); use "
                             "--force to replace them (those not written again are removed)")
        if args.images is not None and target.is_dir() and any(
                photo.parent.resolve() == target.resolve()
                for photo in _image_files(args.images)):
            # Their undistorted copies (NAME.png) could replace the photos themselves.
            raise UsageError(f"--save-undistorted '{target}' is the folder of the photos; "
                             "choose another folder for their undistorted copies")


def _too_few_views(args: argparse.Namespace, board: BoardSpec, found: CollectedViews) -> str:
    """Why ``found`` holds fewer than 3 views, for the error."""
    seen, n = found.seen, len(found.views)
    if found.not_distinct:
        return (f"only {plural(n, 'distinct view')} of the board in {plural(seen, 'frame')} "
                f"of the {_stream_kind(args)}: "
                f"{found.not_distinct} more with the board "
                f"{'was' if found.not_distinct == 1 else 'were'} dropped as not distinct "
                f"(its corners moved less than --min-motion {args.min_motion:g} of the image "
                "diagonal from a view already kept); calibration needs at least 3")
    if not found.views:
        w, h = found.image_size
        if min(w, h) < min_image_side_px(board):
            hint = (f"the views are {w}x{h} px, too small to show a {board.size[0]}x"
                    f"{board.size[1]} board")
        elif board.pattern == "chessboard":
            hint = "check --board: it counts inner corners (a board of 10x7 squares has 9x6)"
        elif board.pattern in ("circles", "acircles"):
            hint = ("check --board (circles per row x rows) and --pattern (circles or "
                    "acircles); the whole grid must be in view")
        else:
            hint = "check --board (squares), --marker-size and --dictionary"
        where = f"any of the {seen} views" if seen != 1 else "the one view"
        return f"the board was not found in {where}; {hint}"
    hint = ("; if it is in more of them, check --board (a wrong size can be found by "
            "chance in a view or two)") if n < seen / 2 else ""
    return (f"the board was found in only {n} of {seen} views; calibration needs at least 3"
            + hint)


def _max_rms_hint(board: BoardSpec, rms_px: float | None) -> str:
    """What to check when the RMS error ``rms_px`` is above ``--max-rms``: up to
    :data:`MAX_RMS_PX` (the default limit) it is what the right board gives, and only a
    stricter ``--max-rms`` refused it; beyond, typically a wrong board
    (docs/benchmarks.md#calibration), though blurred photos can give a few px too."""
    if rms_px is not None and rms_px <= MAX_RMS_PX:
        return (f"an error below the default limit of {MAX_RMS_PX:g} px is what the right "
                "board gives: raise --max-rms to accept it (a wrong --board gives several "
                "px)")
    check = {"chessboard": "check --board: it counts inner corners",
             "charuco": "check --board, --marker-size and --dictionary"}.get(
                 board.pattern, "check --board and --pattern")
    return f"{check} (blurred photos can also give a few px)"


def run(args: argparse.Namespace) -> int:
    for note in _ignored_options(args):
        logger.warning("%s", note)
    args = with_stream_defaults(args)
    board = _board_from_args(args)
    outputs = _outputs(args)
    _check_outputs(args, outputs)

    found = collect_views(args, board, keep_images=args.save_undistorted is not None)
    views, images, size = found.views, found.images, found.image_size
    if len(views) < 3:
        raise UsageError(_too_few_views(args, board, found))
    try:
        calibration = calibrate_views(views, size, board, reject_outliers=not args.no_reject,
                                      max_rms_px=args.max_rms,
                                      uncertainty_limit_px=args.uncertainty_limit)
    except CalibrationError as exc:
        if exc.reason != "corners_do_not_fit":
            raise
        raise CalibrationError(f"{exc} (--max-rms); {_max_rms_hint(board, exc.rms_px)}",
                               exc.reason, exc.rms_px) from None
    result, kept, counts = calibration.result, calibration.views, calibration.coverage
    umap, advice = calibration.uncertainty, list(calibration.warnings)
    for w in advice:
        logger.warning("%s", w)

    from ..viz.plotting import (
        plot_calibration_coverage,
        plot_uncertainty_map,
        plot_view_errors,
        quiet_missing_glyphs,
    )

    extras = calibration.file_metadata()
    undistorted, earlier_copies = [], _earlier_copies(args)
    if args.save_undistorted is not None:
        names = [Path(v.name).stem for v in views]
        if len(set(names)) < len(names):  # a.jpg and a.png: keep both
            names = [Path(v.name).name for v in views]
        undistorted = [args.save_undistorted / f"{name.replace(' ', '_')}.png"
                       for name in names]
        existing = [target for target in undistorted if target.exists()]
        if existing and not args.force:
            raise UsageError(f"'{existing[0]}' exists; use --force to overwrite it")

    # Everything in memory first; the files are written once all of it exists.
    with quiet_missing_glyphs():
        figures = {
            outputs[1].name: _png(plot_calibration_coverage([v.image_points for v in kept],
                                                            size, counts)),
            outputs[2].name: _png(plot_view_errors(result.per_view_errors_px,
                                                   result.rejected_views)),
            outputs[3].name: _png(plot_uncertainty_map(umap)),
        }
    lines = calibration.summary_lines()
    report = None
    if not args.no_report:
        from ..report import calibration_report

        report = calibration_report(lines, calibration.report_numbers(), result.per_view_errors_px,
                                    result.rejected_views, advice, umap, figures)

    # The folder may have gone read-only (or away) during the work: say so in one line.
    require_writable_folder(args.out.parent,
                            f"--out '{args.out}': cannot write in '{args.out.parent}'")
    if args.save_undistorted is not None:
        args.save_undistorted.mkdir(parents=True, exist_ok=True)
    with all_or_nothing():  # a write that fails leaves the earlier files as they were
        written = [save_calibration(args.out, result.as_camera(), extras,
                                    overwrite=args.force)]
        written += [atomic_write_bytes(path, figures[path.name]) for path in outputs[1:4]]
        if report is not None:
            written.append(atomic_write_pieces(outputs[4], report.encoded()))
        for target, img in zip(undistorted, images):  # one undistorted image at a time
            png = cv2.imencode(".png", undistort_image(img, result.K, result.dist))[1]
            written.append(atomic_write_bytes(target, png.tobytes()))
        if args.save_undistorted is not None:
            record = {UNDISTORTED_KEY: str(args.out),
                      FILES_KEY: recorded_files(args.save_undistorted, undistorted)}
            written.append(atomic_write_bytes(args.save_undistorted / UNDISTORTED_RECORD,
                                              json.dumps(record, indent=2).encode()))
    removed = remove_earlier_files(_not_written_again(args))
    if args.save_undistorted is not None:  # an earlier run's copies not written again
        removed += remove_stale_outputs(args.save_undistorted, earlier_copies, written)
    if not args.quiet:
        print("\n".join(lines))
    for path in written:
        print(f"Wrote '{path}'")
    for path in removed:
        print(f"Removed '{path}' (an earlier run's, not written again)")
    if args.show:
        with quiet_missing_glyphs():
            show_images(written[1:4])
    return EXIT_OK


def _unrecognized(args: argparse.Namespace, extra: list[str]) -> str:
    """argparse's error for the arguments ``extra`` it did not recognize, with a hint when
    they are photos: typically the shell expanded an unquoted ``--images`` glob into its
    files (the first one became ``--images``'s value)."""
    message = f"unrecognized arguments: {' '.join(extra)}"
    if args.images is None or not all(Path(a).suffix.lower() in IMAGE_SUFFIXES
                                      for a in extra):
        return message
    shown = " ".join(extra[:3]) + (f" ... ({len(extra)} in all)" if len(extra) > 3 else "")
    # The names' common start and their suffix: left01.jpg left02.jpg -> left*.jpg.
    names = [Path(args.images), *map(Path, extra)]
    start = os.path.commonprefix([n.stem for n in names])
    suffix = names[0].suffix if len({n.suffix for n in names}) == 1 else ""
    example = names[0].parent / f"{start}*{suffix}"
    return (f"unrecognized arguments: {shown}: --images takes one folder or one pattern; "
            f"quote a pattern, as in --images '{example}', or the shell expands it into "
            "file names")


def main(argv: list[str] | None = None, prog: str = "calibrate.py") -> int:
    """Entry point of ``calibrate.py``; returns the exit code."""
    parser = build_parser(prog)
    args, extra = parser.parse_known_args(sys.argv[1:] if argv is None else argv)
    if extra:
        parser.error(_unrecognized(args, extra))
    if args.images is None and args.frames is not None and args.frames < MIN_FRAMES:
        parser.error(f"argument --frames: must be at least {MIN_FRAMES}, got {args.frames}")
    return run_command(args, run)
