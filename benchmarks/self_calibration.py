"""Two-view poses and focal lengths without a calibration file, against a Strecha scene.

    python benchmarks/self_calibration.py SCENE_DIR [--exif none|32|truth|truthx0.7]
                                          [--max-width PX] [--pairs SPEC ...] [--csv FILE]

Runs ``scene3d evaluate SCENE_DIR --no-calib`` (the camera files' intrinsics ignored:
each pair starts from its photos' EXIF focal length, or 1.2 x the longer side, and
self-calibrates) on the scene's photos as they are (``--exif none``: the Strecha JPEGs
carry no EXIF) or on copies that carry an EXIF block with a 35 mm-equivalent focal
length: a number of millimetres, ``truth`` (the camera file's focal length as a 35 mm
equivalent, rounded to whole millimetres as the EXIF tag is: 32 mm for the Strecha
camera, 1 % short of its 32.34 mm) or ``truthxF`` (that times F: a wrong EXIF value,
as a cropped copy would carry). The EXIF block is spliced into the JPEG files after
their first marker, so the pixels, and the matches, are bit for bit those of the
originals. Copies live in a temporary folder, removed at the end; the camera files are
linked. ``scene3d evaluate`` prints the table and the summary.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import math
import re
import sys
import tempfile
from pathlib import Path

from PIL import ExifTags, Image

from scene3D.cli.evaluate import main as evaluate
from scene3D.geometry.intrinsics_prior import focal_35mm_from_px
from scene3D.io.datasets import read_strecha_camera, strecha_views


def exif_segment(focal_35mm: int) -> bytes:
    """A JPEG APP1 segment holding an EXIF block with ``FocalLengthIn35mmFilm``."""
    exif = Image.Exif()
    exif[ExifTags.Base.Make], exif[ExifTags.Base.Model] = "benchmark", "Strecha camera"
    # The sub-IFD as a dict under its pointer: Pillow 9.5 drops values set via get_ifd.
    exif[ExifTags.IFD.Exif] = {ExifTags.Base.FocalLengthIn35mmFilm: focal_35mm}
    payload = exif.tobytes()  # starts with b"Exif\0\0"
    return b"\xff\xe1" + (len(payload) + 2).to_bytes(2, "big") + payload


def with_exif(jpeg: bytes, focal_35mm: int) -> bytes:
    """``jpeg`` with an EXIF segment inserted after its start-of-image marker."""
    if jpeg[:2] != b"\xff\xd8":
        raise ValueError("not a JPEG file")
    return jpeg[:2] + exif_segment(focal_35mm) + jpeg[2:]


def exif_focal_35mm(spec: str, scene: Path) -> int | None:
    """The whole-millimetre 35 mm equivalent that ``--exif`` asks for (None: no EXIF)."""
    if spec == "none":
        return None
    match = re.fullmatch(r"truth(?:x([0-9.]+))?|([0-9]+)", spec)
    if match is None:
        raise SystemExit(f"--exif {spec!r}: use none, a number of mm, truth or truthxF")
    if match.group(2):
        return int(match.group(2))
    camera = read_strecha_camera(strecha_views(scene)[0][1])
    focal = math.sqrt(camera.K[0, 0] * camera.K[1, 1]) * float(match.group(1) or 1.0)
    return round(focal_35mm_from_px(focal, camera.image_size))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scene", type=Path, help="a scene in the Strecha layout")
    parser.add_argument("--exif", default="none",
                        help="none, a 35 mm-equivalent focal length in mm, truth or truthxF")
    parser.add_argument("--max-width", default="1536", help="passed to scene3d evaluate")
    parser.add_argument("--pairs", nargs="+", default=["consecutive"],
                        help="passed to scene3d evaluate")
    parser.add_argument("--csv", type=Path, help="passed to scene3d evaluate (with --force)")
    args = parser.parse_args(argv)
    focal_35mm = exif_focal_35mm(args.exif, args.scene)
    extra = ["--max-width", args.max_width, "--pairs", *args.pairs, "--no-calib", "-q"]
    if args.csv is not None:
        extra += ["--csv", str(args.csv), "--force"]
    if focal_35mm is None:
        print(f"{args.scene.name}: photos without EXIF", flush=True)
        return evaluate([str(args.scene), *extra])
    with tempfile.TemporaryDirectory(prefix="scene3d-exif-") as tmp:
        copy = Path(tmp) / args.scene.name
        (copy / "images").mkdir(parents=True)
        (copy / "gt_dense_cameras").mkdir()
        for image, camera in strecha_views(args.scene):
            (copy / "images" / image.name).write_bytes(with_exif(image.read_bytes(),
                                                                 focal_35mm))
            (copy / "gt_dense_cameras" / camera.name).symlink_to(camera.resolve())
        print(f"{args.scene.name}: photos with EXIF FocalLengthIn35mmFilm {focal_35mm} mm",
              flush=True)
        return evaluate([str(copy), *extra])


if __name__ == "__main__":
    sys.exit(main())
