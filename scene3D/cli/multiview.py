"""``scene3d reconstruct-views``: cameras and points from many photos."""

from __future__ import annotations

import argparse
import logging
import os
import re
import sys
import time
from pathlib import Path

from ..calibration.views import VIDEO_SUFFIXES
from ..errors import ReconstructionError, plural
from ..features.matching import FEATURE_MODES
from ..geometry.camera import adapt_intrinsics_to_size
from ..geometry.intrinsics_prior import CAMERA_MODES
from ..geometry.lens import CAMERA_MODELS
from ..io.calibration import load_calibration
from ..io.datasets import CameraFilesError, StrechaCamera, read_strecha_cameras
from ..io.export import all_or_nothing, colmap_image_name, write_json, written_bytes
from ..io.images import BOOK_MAX_WIDTH_PX, read_image_size
from ..io.model_folder import MODEL_FIGURE, MODEL_FILES, model_folder_name
from ..io.model_folder import write_model as write_model_folder
from ..io.nerfstudio import write_nerfstudio
from ..io.paths import image_files
from ..io.undistorted import UNDISTORTED_FOLDER
from ..multiview import (
    PAIR_MODES,
    MultiViewReconstruction,
    SfMModel,
    SfMSettings,
    reconstruct_views,
)
from ..multiview.pipeline import default_focal_prior
from ..multiview.summary import CALIBRATION_QUESTION
from ..multiview.video import MAX_FRAMES, MIN_MOTION
from .common import (
    EXIT_FAILED,
    EXIT_OK,
    ArgumentParser,
    UsageError,
    add_common_args,
    add_engine_args,
    add_feature_arg,
    add_size_args,
    check_image_paths,
    check_report_viewer,
    exit_codes_help,
    non_negative_int,
    note_created_folders,
    open_engine,
    path_arg,
    positive_int,
    read_camera_priors,
    run_command,
)
from .dense_views import (
    CLOUD_FILE,
    MESH_FILE,
    dense_files,
    reconstruction_dense,
    require_mesh_extra,
    write_dense,
)
from .dense_views import SUMMARY_FILE as DENSE_SUMMARY_FILE
from .outputs import FILES_KEY, SUMMARY_FILE, OutputFolder
from .video import FRAMES_FOLDER, read_video, video_source, write_frames, write_undistorted
from .views_lines import model_name, result_lines

logger = logging.getLogger("scene3D.cli")

REPORT_FILE = "report.html"

#: A model with fewer points than this is a failure (``SfMSettings.min_model_points``).
MIN_MODEL_POINTS = SfMSettings.min_model_points

#: What --export can write, and nerfstudio's file in a model's folder.
EXPORT_FORMATS = ("nerfstudio",)
CAMERA_MODEL_CHOICES = ("auto", *CAMERA_MODELS)
#: Where ``--dense`` writes, inside ``--out``.
DENSE_FOLDER = "dense"
CAMERA_MODE_CHOICES = tuple(mode.replace("_", "-") for mode in CAMERA_MODES)
NERFSTUDIO_FILE = "transforms.json"


def build_parser(prog: str = "scene3d reconstruct-views") -> argparse.ArgumentParser:
    parser = ArgumentParser(
        prog=prog,
        description=(
            "Incremental structure from motion: register many photos and triangulate "
            "their points, with bundle adjustment. The photos are grouped into cameras "
            "(--camera-mode: by EXIF camera, focal length and image size). Without --calib "
            "each camera's focal length starts from its EXIF (or 1.2 x the longer side) and "
            "is refined by the photos with its lens distortion (--camera-model)."
        ),
        epilog=(
            "Writes into --out: points.ply (binary, RGB), cameras.json (world-to-camera "
            "poses, K, distortion and size of the photos), colmap/cameras.txt, images.txt, "
            "points3D.txt (a COLMAP text model of the photos at their own size), "
            "cameras.png (cloud with camera frusta) and with --export nerfstudio "
            f"{NERFSTUDIO_FILE} for the largest model, the same files "
            "in model-1/, model-2/, ... for further models (views that connect among "
            "themselves but not to the first), and reconstruction.json (summary: which "
            "views are in which model, which are in none and why) and report.html (the "
            "summary with an interactive 3D view of the largest model; opens offline). "
            "Files of those names in --out are replaced, and the files of an earlier "
            "run there (as its reconstruction.json lists them) that this run does not "
            "write again are removed; other files are kept. A model that fails the "
            "consistency check (a view whose pose contradicts its pair geometry, a fold) "
            f"or has fewer than {MIN_MODEL_POINTS} points is "
            "written all the same, for inspection (replacing the earlier run's files), its "
            "status 'failed', and the exit code is 1; when no model can start or be kept, "
            "nothing is written (an earlier run's files stay). Views are named by their "
            "file names (two photos of one name are refused); colmap/images.txt, which "
            "cannot hold spaces, has '_' for each. From a video (or --camera) the views "
            "are frames picked by motion and sharpness (each kept frame named on stderr "
            f"with why, then one summary line): no blurred frame, each {100 * MIN_MOTION:g} "
            "% of the image diagonal of median image motion from the frame kept before, "
            "at most --max-frames (from a file, thinned to every other frame as often as "
            "needed to stay within it); they are named by their time in the video "
            "('t012.40s'), their focal length starts at 1.2 x the longer side (a video has "
            f"no EXIF), and --export nerfstudio writes them as {FRAMES_FOLDER}/NAME.png. "
            + exit_codes_help("no pair gives a trustworthy start or the check leaves no "
                              "model, a model failed its "
                              f"consistency check or has fewer than {MIN_MODEL_POINTS} "
                              "points, or the cluster gave a task up") + "."
        ),
    )
    parser.add_argument("images", nargs="*", metavar="IMAGES",
                        help="image files, a folder, or quoted globs such as 'photos/*.jpg'; "
                             "or one video file (" + " ".join(sorted(VIDEO_SUFFIXES)) +
                             ", or any file OpenCV reads as a video and not as an image)")
    parser.add_argument("--camera", type=non_negative_int, metavar="INDEX",
                        help="instead of IMAGES, frames of this webcam (0: the first), "
                             "read until --max-frames are kept")
    parser.add_argument("--max-frames", type=positive_int, default=MAX_FRAMES, metavar="N",
                        help="from a video or --camera: the most frames kept (default "
                             f"{MAX_FRAMES}, at least 2)")
    parser.add_argument("--calib", type=Path, metavar="FILE",
                        help="camera calibration (OpenCV YAML/XML as calibrate.py writes it; "
                             "a focal length the photos refute by more than 2 %% is replaced "
                             "by the one they call for, with a warning); without it each "
                             "camera's focal length is found from the photos (cameras as "
                             "--camera-mode groups them; principal point at the centre, with "
                             "the lens distortion of --camera-model; the documentation's page "
                             "'Photos without a calibration file')")
    parser.add_argument("--camera-model", choices=CAMERA_MODEL_CHOICES, default="auto",
                        help="without --calib: 'simple_radial' (a focal length and one "
                             "radial distortion coefficient, found from the photos; what "
                             "'auto', the default, means), 'radial' (two coefficients) or "
                             "'pinhole' (no distortion); with --calib the file gives the "
                             "camera")
    parser.add_argument("--camera-mode", choices=CAMERA_MODE_CHOICES, default="auto",
                        help="without --calib, which photos share a camera: 'auto', the "
                             "default (one camera per image size, EXIF make and model and "
                             "EXIF focal length, as COLMAP groups them), 'single' (all "
                             "photos, which must then be of one size) or 'per-photo' (every "
                             "photo its own focal length and lens: internet photos, a zoom "
                             "changed between shots)")
    add_size_args(parser, 2 * BOOK_MAX_WIDTH_PX, "3072 -> 1536, half resolution")
    parser.add_argument("--pairs", choices=PAIR_MODES, default="auto",
                        help="which pairs to match: 'retrieval' (each view with its "
                             "--retrieval-neighbours most similar views, any order), "
                             "'sequential' (each with its --neighbours followers in the "
                             "given order), 'all', or 'auto', the default (all pairs up to "
                             "2K+1 views, K being --retrieval-neighbours, else retrieval, "
                             "plus sequential when the images show that the given order is "
                             "a sequence; the summary says which)")
    parser.add_argument("--neighbours", type=positive_int, default=3, metavar="N",
                        help="sequential pairs: how many following views each view is "
                             "matched with (default 3)")
    parser.add_argument("--retrieval-neighbours", type=positive_int, default=8, metavar="K",
                        help="retrieval: how many most similar views each view is matched "
                             "with (default 8)")
    add_feature_arg(parser, [m.lower() for m in FEATURE_MODES if m != "flow"])
    parser.add_argument("--ground-truth", type=Path, metavar="DIR",
                        help="Strecha .camera files (NAME.camera per image): report camera "
                             "errors after a similarity alignment")
    parser.add_argument("--out", type=path_arg, default=Path("out/views"), metavar="DIR",
                        help="output folder (default: out/views), not that of the "
                             "photos: a run replaces an earlier run's files there named as "
                             "its outputs (below) and removes those it does not write again "
                             "(as listed in that run's reconstruction.json); other files "
                             "are kept, and a file named as an output that no earlier run "
                             "wrote stops the run (exit code 2)")
    parser.add_argument("--export", action="append", choices=EXPORT_FORMATS, default=[],
                        help="also write each model for other tools: 'nerfstudio', its "
                             f"{NERFSTUDIO_FILE} (nerfstudio's format, which instant-ngp and "
                             "Gaussian-splatting trainers read: the photos' cameras, "
                             "camera-to-world in OpenGL axes, paths relative to it); default: none")
    parser.add_argument("--undistort", action="store_true",
                        help="with --export nerfstudio: the images of the models undistorted "
                             f"as {UNDISTORTED_FOLDER}/NAME.png (PNG, at the size and with the "
                             "camera matrix of their camera; what the lens did not see is "
                             f"black), which {NERFSTUDIO_FILE} names, with no distortion")
    parser.add_argument("--dense", action="store_true",
                        help=f"also a dense cloud of the largest model, as scene3d dense-views "
                             f"makes it: {DENSE_FOLDER}/{CLOUD_FILE} and "
                             f"{DENSE_FOLDER}/{DENSE_SUMMARY_FILE} (photos only, not a video); "
                             f"{REPORT_FILE} then shows it (or the mesh) and each view's "
                             "depth map")
    parser.add_argument("--mesh", action="store_true",
                        help=f"with --dense: also its surface, {DENSE_FOLDER}/{MESH_FILE} "
                             "(screened Poisson; the mesh extra, Open3D)")
    parser.add_argument("--no-plots", action="store_true", help="skip cameras.png")
    parser.add_argument("--no-report", action="store_true",
                        help="skip report.html (one self-contained page: the numbers, the "
                             "figure and an interactive 3D view of the points and cameras)")
    add_engine_args(parser)
    add_common_args(parser)
    return parser


def image_paths(specs: list[str]) -> list[Path]:
    """Files, folders and globs in the order given (:func:`scene3D.io.paths.image_files`);
    refused (:class:`UsageError`) when fewer than two, one file comes twice or two share a
    name."""
    paths = image_files(specs)
    if len(paths) < 2:
        raise UsageError(f"need at least two images, got {len(paths)}")
    check_image_paths(paths)
    check_view_names(paths)
    return paths


def check_view_names(paths: list[Path]) -> None:
    """Raise :class:`UsageError` when two photos share a file name (from two folders), or
    two would share one in COLMAP's images.txt (:func:`~scene3D.io.export.colmap_image_name`):
    the outputs name the views by it."""
    seen: dict[str, Path] = {}
    for path in paths:
        if path.name in seen:
            raise UsageError(f"two photos are named '{path.name}' ('{seen[path.name]}', "
                             f"'{path}'): the outputs name views by file name; rename one")
        seen[path.name] = path
    in_colmap: dict[str, Path] = {}
    for path in paths:
        other = in_colmap.setdefault(colmap_image_name(path.name), path)
        if other is not path:
            raise UsageError(f"'{path.name}' and '{other.name}' would both be "
                             f"'{colmap_image_name(path.name)}' in colmap/images.txt, which "
                             "cannot hold spaces in names; rename one")


def check_out_folder(out: Path, paths: list[Path]) -> None:
    """Raise :class:`UsageError` when ``--out`` is the folder of some of the photos, or
    holds them where a run writes (``colmap/``, ``model-N/``): the figures and files
    written there would be read as photos by the next run, or replace them."""
    inside = out.resolve()  # also where 'new/../photos' leads, before 'new' exists
    for photo in paths:
        folder = photo.parent.resolve()
        if folder == inside:
            raise UsageError(f"--out '{out}' is the folder of the photos; choose another "
                             "folder for the outputs")
        if inside in folder.parents:
            first = folder.relative_to(inside).parts[0]
            if first == "colmap" or re.fullmatch(r"model-\d+", first):
                raise UsageError(f"--out '{out}' holds the photos in '{photo.parent}', "
                                 "where a run writes; choose another folder for the outputs")


def read_ground_truth(folder: Path, paths: list[Path]) -> list[StrechaCamera]:
    """The Strecha camera of every photo (``folder/NAME.camera``), read and checked
    before any work (:func:`scene3D.io.datasets.read_strecha_cameras`): a missing or invalid
    file, or one for images of another aspect ratio than its photo's, is a one-line input
    error that names ``--ground-truth``."""
    try:
        return read_strecha_cameras(folder, paths)
    except CameraFilesError as exc:
        raise UsageError(f"--ground-truth '{exc.path}' {exc.problem}") from None


def _failure_message(recon: MultiViewReconstruction, names: list[str]) -> str:
    """Why a reconstruction failed its consistency check, in one line."""
    bad = [names[v] for model in recon.models for v in model.check.suspect_views]
    why = [f"the poses of {', '.join(bad)} contradict their pair geometry"] if bad else []
    refuting = [model.check for model in recon.models if model.check.focal_mismatch]
    if refuting:
        check, refits = refuting[0], len(recon.focal_refits)
        scale = check.focal_scale * recon.focal_refit_scale  # over the calibration's
        after = (f", still after {plural(refits, 'reconstruction')} with the focal "
                 "length they called for" if refits else "")
        why.append(f"the views fit a focal length {scale:.3f} times the calibration's "
                   f"(+-{scale * check.focal_scale_sigma_log:.2g}){after}: "
                   f"{CALIBRATION_QUESTION}")
    return (f"the reconstruction failed its consistency check: {'; '.join(why)} "
            "(see reconstruction.json; the files are written for inspection only)")


def _write_report(out: Path, recon: MultiViewReconstruction, summary: dict, lines: list[str],
                  warnings: list[str], plots: bool, sources: list, dense: tuple | None) -> Path:
    """report.html (:func:`scene3D.report.reconstruction_report`), with the dense run."""
    from ..io.export import atomic_write_pieces
    from ..report import DenseRun, reconstruction_report
    from .report import thumbnails

    figures = {"cameras.png": written_bytes(out / "cameras.png")} if plots else {}
    page = reconstruction_report(
        recon, _placed(recon.names, summary["models"]), summary, lines, warnings, figures,
        thumbnails(sources, recon.names),
        None if dense is None else DenseRun(tuple(dense[0].names), *dense[1:]))
    return atomic_write_pieces(out / REPORT_FILE, page.encoded())


def _placed(names: list[str], models: list[dict]) -> list[str | None]:
    """For each view the model it is in (:func:`~scene3D.cli.views_lines.model_name`;
    ``models``: the summary's entries), None when in none."""
    label = {view: model_name(m, entry["folder"])
             for m, entry in enumerate(models) for view in entry["views"]}
    return [label.get(name) for name in names]


def _run_warnings(recon: MultiViewReconstruction, models: list[dict], summary: dict
                  ) -> list[str]:
    """What the command warns of (stderr and the report): views in no model, doubts about
    each model's focal length, a calibration the views refuted."""
    by_reason: dict[str, list[str]] = {}  # views left out for one reason: one line
    for name in recon.unregistered:
        by_reason.setdefault(recon.unregistered_reasons.get(name, "unknown"), []).append(name)
    warnings = [f"{'view' if len(views) == 1 else 'views'} "
                f"{', '.join(repr(n) for n in views)} could not be registered: {reason}"
                for reason, views in by_reason.items()]
    for m, (entry, model) in enumerate(zip(models, recon.models)):
        whose = "" if m == 0 else f"{model_name(m, entry['folder'])}: "
        if model.focal is not None:
            warnings += [f"{whose}focal length: {message}" for message in model.focal.warnings]
    return warnings + list(summary["warnings"])


def write_model(folder: Path, names: list[str], recon: MultiViewReconstruction,
                model: SfMModel, plots: bool) -> list[Path]:
    """The files of one model (:func:`scene3D.io.model_folder.write_model`; ``names`` are
    ``recon.names``); the folders it creates are removed again if the run fails."""
    created: list[Path] = []
    try:
        return write_model_folder(folder, recon, model, plots, created)
    finally:
        note_created_folders(created)


def run(args: argparse.Namespace) -> int:
    t_start = time.perf_counter()
    if args.calib is not None and args.camera_model not in ("auto", "pinhole"):
        raise UsageError(f"--camera-model {args.camera_model} is for photos without --calib: "
                         "the calibration file gives the camera (its distortion included)")
    if args.undistort and "nerfstudio" not in args.export:
        raise UsageError("--undistort is for --export nerfstudio (the images it names)")
    video = video_source(args)
    if args.mesh and not args.dense:
        raise UsageError("--mesh is for --dense (the surface of the dense cloud)")
    if args.dense and video is not None:
        raise UsageError("--dense needs photos: with a video, run it on frames saved as "
                         "photos, or scene3d dense-views on the model and the frames")
    if args.mesh:
        require_mesh_extra()
    if video is not None and args.ground_truth is not None:
        raise UsageError("--ground-truth needs photos (NAME.camera per photo), not a video")
    if video is None and args.max_frames != MAX_FRAMES:
        logger.warning("--max-frames is for a video or --camera; ignored with photos")
    paths = [] if video is not None else image_paths(args.images)
    check_out_folder(args.out, paths)
    prior = None
    if args.calib is not None:
        camera = load_calibration(args.calib)
    elif video is None:  # the cameras, or a one-line error (exit code 2)
        camera_mode = args.camera_mode.replace("-", "_")
        _, priors = read_camera_priors(paths, camera_mode)
        prior = priors[0] if len(priors) == 1 else None
    names = [p.name for p in paths]
    truth = None if args.ground_truth is None else read_ground_truth(args.ground_truth, paths)
    model_names = (*MODEL_FILES, MODEL_FIGURE, NERFSTUDIO_FILE)
    out_folder = OutputFolder(args.out, inputs=[*paths, *filter(None, [args.calib]),
                                                *([video] if isinstance(video, Path) else [])],
                              names=(*model_names, *(f"model-*/{n}" for n in model_names),
                                     f"{FRAMES_FOLDER}/*.png", f"{UNDISTORTED_FOLDER}/*.png",
                                     *(f"{DENSE_FOLDER}/{n}" for n in (
                                         CLOUD_FILE, MESH_FILE, DENSE_SUMMARY_FILE)),
                                     SUMMARY_FILE, REPORT_FILE))
    out = out_folder.path
    # Before the work: the first model's files, and those of further models already there
    # (how many models come out is known only at the end, when all are checked again).
    out_folder.check_free([*(out / name for name in (
        *MODEL_FILES, *([] if args.no_plots else [MODEL_FIGURE]), SUMMARY_FILE,
        *([NERFSTUDIO_FILE] if "nerfstudio" in args.export else []),
        *([] if args.no_report else [REPORT_FILE]))),
        *(dense_files(out / DENSE_FOLDER, args.mesh) if args.dense else []),
        *(p for p in out_folder.matching() if p.relative_to(out).parts[0].startswith("model-"))])
    if not args.no_report:
        check_report_viewer()

    sources: list = list(paths)
    if video is not None:
        chosen = read_video(video, args.max_frames, args.quiet)
        sources, names = chosen.images, chosen.names
        if args.calib is None and sources:
            prior = default_focal_prior(sources, names)
    if args.calib is not None:
        K_native = adapt_intrinsics_to_size(camera.K, camera.image_size, chosen.image_size
                                            if video is not None else read_image_size(paths[0]))
        dist = camera.dist
    else:
        K_native, dist = None, None

    def progress(message: str) -> None:
        if not args.quiet:
            print(message, file=sys.stderr)

    with open_engine(args) as engine:
        recon = reconstruct_views(
            sources, K_native, dist,
            max_width=None if args.no_pyr_down else args.max_width, names=names,
            feature=args.feature, pairs=args.pairs,
            settings=SfMSettings(neighbours=args.neighbours,
                                 retrieval_neighbours=args.retrieval_neighbours),
            progress=progress, engine=engine, focal_prior=prior,
            camera_model=args.camera_model, camera_mode=args.camera_mode.replace("-", "_"))
        dense, dense_failure, t_dense = None, None, time.perf_counter()
        if args.dense and recon.ok:
            try:
                dense = reconstruction_dense(recon, paths, engine, args.mesh)
            except ReconstructionError as exc:  # the sparse model is written all the same
                dense_failure = f"--dense: {exc}"
    # The files of every model, all or none: a write that fails leaves the earlier run's.
    with all_or_nothing():
        written: list[Path] = []
        images = dict(zip(names, sources))  # photos' paths, or a video's frames
        if video is not None and "nerfstudio" in args.export and not args.undistort:
            images = write_frames(out / FRAMES_FOLDER, recon, sources)
            written += images.values()
        for m, model in enumerate(recon.models):
            folder = out / model_folder_name(m)
            written += write_model(folder, names, recon, model, not args.no_plots)
            if "nerfstudio" in args.export:
                colmap, model_images = recon.colmap_model(model), images
                if args.undistort:
                    colmap, model_images = write_undistorted(out / UNDISTORTED_FOLDER, colmap,
                                                             images)
                    written += model_images.values()
                written.append(write_nerfstudio(folder / NERFSTUDIO_FILE, colmap, model_images,
                                                ply_file=folder / MODEL_FILES[0]))
        dense_line = None
        if dense is not None:
            folder = os.path.commonpath([str(p.parent) for p in paths])
            dense_written, dense_line = write_dense(
                out / DENSE_FOLDER, *dense, {"model": str(out), "images": folder}, t_dense)
            written += dense_written
        summary = recon.to_dict(None if prior is None else prior.camera_name, truth)
        if video is not None:  # which frames the views are, and why those
            summary["video"] = {"source": str(video), **chosen.to_dict()}
        models = summary["models"]
        timings = {k: v for k, v in recon.timings_s.items() if k != "total"}
        timings["total"] = time.perf_counter() - t_start
        summary["timings_s"] = timings
        summary[FILES_KEY] = out_folder.record([
            *written, out / SUMMARY_FILE, *([] if args.no_report else [out / REPORT_FILE])])
        written.append(write_json(out / SUMMARY_FILE, summary))
        lines = result_lines(names, recon, models)
        warnings = _run_warnings(recon, models, summary)
        if not args.no_report:
            written.append(_write_report(out, recon, summary, lines, warnings,
                                         not args.no_plots, sources, dense))
    removed = out_folder.remove_stale(written)

    in_colmap = {names[v] for model in recon.models for v in model.views}
    renamed = [n for n in names if n in in_colmap and colmap_image_name(n) != n]
    if renamed:
        more = f" (and {len(renamed) - 1} more)" if len(renamed) > 1 else ""
        logger.warning("COLMAP's text format cannot hold names with spaces: "
                       "colmap/images.txt has '%s' for '%s'%s, '_' for each space, so those "
                       "names do not match the files; rename the photos for tools that open "
                       "them", colmap_image_name(renamed[0]), renamed[0], more)
    for message in warnings:
        logger.warning("%s", message)
    if not args.quiet:
        lines[0] += f", {timings['total']:.1f} s"
        if dense_line is not None:
            lines.append(f"dense: {dense_line}")
        print("\n".join(lines))
    for path in written:
        print(f"Wrote '{path}'")
    for path in removed:
        print(f"Removed '{path}' (an earlier run's, not written again)")
    for m in recon.thin_models:
        entry = models[m]
        print(f"error: {model_name(m, entry['folder'])} has {plural(entry['points'], 'point')} "
              f"for its {entry['registered']} views, fewer than {recon.min_model_points}: its "
              "cameras rest on nothing (does the calibration fit these photos?); see "
              "reconstruction.json, the files are written for inspection only",
              file=sys.stderr)
    if not recon.consistent:
        print(f"error: {_failure_message(recon, names)}", file=sys.stderr)
    if dense_failure is not None:
        print(f"error: {dense_failure}", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK if recon.ok else EXIT_FAILED


def main(argv: list[str] | None = None, prog: str = "scene3d reconstruct-views") -> int:
    args = build_parser(prog).parse_args(sys.argv[1:] if argv is None else argv)
    return run_command(args, run)
