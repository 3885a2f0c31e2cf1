"""``scene3d export MODEL --to nerfstudio --images DIR``: a COLMAP model (text or binary,
from COLMAP, hloc or scene3D, or a ``reconstruct-views`` output folder) for other tools.

The command parses, checks what it would replace, and makes one library call
(:func:`scene3D.io.nerfstudio.export_nerfstudio`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..io.colmap import find_model_folder, read_colmap_model
from ..io.model_files import COLMAP_FOLDER
from ..io.nerfstudio import (
    NERFSTUDIO_FILE,
    NERFSTUDIO_POINTS_FILE,
    NerfstudioCameraError,
    export_nerfstudio,
    nerfstudio_export_files,
)
from ..io.undistorted import UNDISTORTED_FOLDER, check_model_images
from .common import EXIT_OK, ArgumentParser, UsageError, add_common_args, run_command
from .outputs import prepare_output_dir

#: What --to can write.
EXPORT_FORMATS = ("nerfstudio",)


def build_parser(prog: str = "scene3d export") -> argparse.ArgumentParser:
    parser = ArgumentParser(
        prog=prog,
        description="Write a COLMAP model (cameras, images and points3D, .txt or .bin, from "
                    "COLMAP, hloc or scene3D) for other tools: 'nerfstudio' writes "
                    f"{NERFSTUDIO_FILE} (nerfstudio's format, which instant-ngp and gsplat "
                    "read: camera-to-world matrices in OpenGL axes, the lens as OPENCV) and "
                    f"the points as {NERFSTUDIO_POINTS_FILE} for splatting trainers.",
        epilog="Exit codes: 0 success; 2 bad usage or input (a model file missing or "
               "malformed, an image missing or of another size than its camera, a file "
               "that would be replaced without --force); nothing is written then")
    parser.add_argument("model", type=Path, metavar="MODEL",
                        help="folder with cameras, images and points3D (.txt or .bin; the "
                             "binary ones first when all three are there, as COLMAP does), "
                             f"or a reconstruct-views output folder (its {COLMAP_FOLDER}/, "
                             "the largest model)")
    parser.add_argument("--to", required=True, choices=EXPORT_FORMATS,
                        help="the format to write")
    parser.add_argument("--images", type=Path, required=True, metavar="DIR",
                        help="the photos the model was made from (its image names relative "
                             "to it), at the size its cameras say")
    parser.add_argument("--out", type=Path, metavar="DIR",
                        help="where to write (default: MODEL); file paths in "
                             f"{NERFSTUDIO_FILE} are relative to it")
    parser.add_argument("--undistort", action="store_true",
                        help=f"also write each image undistorted (PNG) into "
                             f"OUT/{UNDISTORTED_FOLDER}/ and name those, with pinhole "
                             "cameras: for trainers that model no lens distortion")
    parser.add_argument("--force", action="store_true",
                        help=f"replace the {NERFSTUDIO_FILE}, {NERFSTUDIO_POINTS_FILE} and "
                             "copies already in OUT (an earlier export's)")
    add_common_args(parser)
    return parser


def run(args: argparse.Namespace) -> int:
    if not args.model.is_dir():
        raise UsageError(f"MODEL '{args.model}' is not a folder")
    if not args.images.is_dir():
        raise UsageError(f"--images '{args.images}' is not a folder")
    out = args.out if args.out is not None else args.model
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out '{out}' exists and is not a folder")
    # A bad model, or none (the reader names the file missing): exit code 2.
    model = read_colmap_model(find_model_folder(args.model) or args.model)
    check_model_images(model, args.images)  # before "exists": a wrong --images first
    inputs = {(args.images / name).resolve() for name in model.names}
    for path in nerfstudio_export_files(out, model, args.undistort):
        if path.resolve() in inputs:
            raise UsageError(f"the export would write '{path}', one of the images it "
                             "reads; choose another --out")
        if path.exists() and not args.force:
            raise UsageError(f"'{path}' exists (--force replaces it)")
    prepare_output_dir(out)  # removed again when the export fails
    try:
        written = export_nerfstudio(out, model, args.images, undistort=args.undistort)
    except NerfstudioCameraError as exc:
        raise UsageError(f"{exc}; --undistort writes its images undistorted, with pinhole "
                         "cameras") from None
    if not args.quiet:
        cameras = len(model.cameras)
        print(f"{len(model.names)} images, {len(model.points3d)} points, "
              f"{cameras} camera{'s' if cameras != 1 else ''}")
    for path in written:
        print(f"Wrote '{path}'")
    return EXIT_OK


def main(argv: list[str] | None = None, prog: str = "scene3d export") -> int:
    args = build_parser(prog).parse_args(sys.argv[1:] if argv is None else argv)
    return run_command(args, run)
