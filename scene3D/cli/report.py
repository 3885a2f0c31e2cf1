"""``scene3d report MODEL_DIR``: the self-contained report of any COLMAP model (text or
binary), and
what the commands' reports read from disk (the views' thumbnails)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from ..io.colmap import read_colmap_model
from .common import (
    EXIT_OK,
    ArgumentParser,
    UsageError,
    add_common_args,
    check_report_viewer,
    run_command,
)

#: Thumbnail height in pixels (shown at half that: sharp on high-density screens).
THUMBNAIL_HEIGHT = 96
#: The most views a report shows a thumbnail of (about 5 KB each), evenly spaced beyond.
MAX_THUMBNAILS = 300


def thumbnail_jpeg(source: str | Path | np.ndarray, height: int = THUMBNAIL_HEIGHT
                   ) -> bytes | None:
    """A small JPEG of a photo (a path, decoded at 1/8 size where the format allows) or of
    a BGR image; None when the file cannot be read.

    Parameters
    ----------
    source : str, Path or (H, W, 3) uint8 ndarray
        The photo.
    height : int, default THUMBNAIL_HEIGHT
        The thumbnail's height in pixels.

    Returns
    -------
    bytes or None
    """
    from ..viz.drawing import encode_jpeg

    if isinstance(source, np.ndarray):
        image = source
    else:
        try:
            data = np.fromfile(str(source), dtype=np.uint8)  # any path, non-ASCII too
        except OSError:
            return None
        image = cv2.imdecode(data, cv2.IMREAD_REDUCED_COLOR_8)
        if image is None:
            return None
    if image.ndim == 2:
        image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    h, w = image.shape[:2]
    width = max(1, round(w * height / h))
    small = cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)
    return encode_jpeg(small, quality=75)


def thumbnails(sources: Sequence[str | Path | np.ndarray], names: Sequence[str],
               limit: int = MAX_THUMBNAILS) -> dict[str, bytes]:
    """:func:`thumbnail_jpeg` of each view that can be read, by name; of ``limit`` views
    evenly spaced (the first and the last among them) when there are more.

    Parameters
    ----------
    sources : sequence of path or ndarray
        The views as the command read them (paths, or video frames).
    names : sequence of str
        Their names, one per source.
    limit : int, default MAX_THUMBNAILS
        The most thumbnails made (each photo read costs time; each thumbnail about 5 KB).

    Returns
    -------
    dict of str to bytes
    """
    if limit < 1:
        raise ValueError(f"limit must be at least 1, got {limit}")
    chosen = range(len(names))
    if len(names) > limit:
        chosen = np.unique(np.rint(np.linspace(0, len(names) - 1, limit)).astype(int))
    out = {}
    for v in chosen:
        name, source = names[v], sources[v]
        jpg = thumbnail_jpeg(source)
        if jpg is not None:
            out[name] = jpg
    return out


def build_parser(prog: str = "scene3d report") -> argparse.ArgumentParser:
    parser = ArgumentParser(
        prog=prog,
        description="Write the self-contained HTML report of a COLMAP model "
                    "(cameras, images and points3D, .txt or .bin), from COLMAP, hloc or "
                    "scene3D: the cameras, the points, each view's numbers and the "
                    "interactive 3D view.",
        epilog="Exit codes: 0 success; 2 bad usage or input (a model file missing or "
               "malformed)")
    parser.add_argument("model", type=Path, metavar="MODEL_DIR",
                        help="folder with cameras.txt, images.txt and points3D.txt, or "
                             "their .bin forms (taken first when all three are there, as "
                             "COLMAP does)")
    parser.add_argument("--images", type=Path, metavar="DIR",
                        help="the photos (IMAGE names relative to it), for thumbnails")
    parser.add_argument("--out", type=Path, metavar="FILE",
                        help="the page to write (default: MODEL_DIR/report.html)")
    parser.add_argument("--force", action="store_true",
                        help="replace an existing page")
    add_common_args(parser)
    return parser


def run(args: argparse.Namespace) -> int:
    from ..io.export import atomic_write_pieces
    from ..report import colmap_report

    if not args.model.is_dir():
        raise UsageError(f"MODEL_DIR '{args.model}' is not a folder")
    out = args.out if args.out is not None else args.model / "report.html"
    if out.exists() and not args.force:
        raise UsageError(f"'{out}' exists (--force replaces it)")
    if not out.parent.is_dir():
        raise UsageError(f"--out '{out}': the folder '{out.parent}' does not exist")
    check_report_viewer()
    model = read_colmap_model(args.model)  # a missing file or a bad record: exit code 2
    thumbs = {}
    if args.images is not None:
        if not args.images.is_dir():
            raise UsageError(f"--images '{args.images}' is not a folder")
        thumbs = thumbnails([args.images / n for n in model.names], model.names)
    page = colmap_report(model, str(args.model), thumbs)
    written = atomic_write_pieces(out, page.encoded())
    if not args.quiet:
        print(f"{len(model.names)} images, {len(model.points3d)} points, "
              f"{len(model.cameras)} camera{'s' if len(model.cameras) != 1 else ''}")
    print(f"Wrote '{written}'")
    return EXIT_OK


def main(argv: list[str] | None = None, prog: str = "scene3d report") -> int:
    args = build_parser(prog).parse_args(sys.argv[1:] if argv is None else argv)
    return run_command(args, run)
