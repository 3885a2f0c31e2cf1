"""``scene3d reconstruct-views`` from a video or a webcam: which source, the frames
kept (:mod:`scene3D.multiview.video`) with the lines saying why, and the images written
for the tools that read them (the frames, or any model's images undistorted)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

from ..calibration.views import VIDEO_SUFFIXES, read_frames
from ..io.colmap_model import ColmapModel
from ..io.export import write_png
from ..io.undistorted import write_undistorted_images
from ..multiview import MultiViewReconstruction
from ..multiview.video import VideoFrames, select_frames
from .common import UsageError, note_created_folders

#: From a video, the kept frames for --export nerfstudio (the trainers read images).
FRAMES_FOLDER = "frames"


def quiet_ffmpeg() -> None:
    """FFmpeg's own lines ("moov atom not found") off, unless the environment sets its
    level: the command says in one line what failed. Before the first video is opened."""
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")


def video_source(args: argparse.Namespace) -> Path | int | None:
    """The video (a file, or ``--camera``'s index) the run reads, None for photos; a
    file is a video by its ending, or when OpenCV has no image reader for it but opens
    it as a video."""
    if args.camera is not None:
        if args.images:
            raise UsageError("give IMAGES or --camera, not both")
        return args.camera
    if not args.images:
        raise UsageError("give IMAGES (photos, a folder, a glob or a video) or --camera")
    path = Path(args.images[0])
    if len(args.images) > 1:
        return None
    if path.suffix.lower() in VIDEO_SUFFIXES:
        return path  # also when missing: "video not found"
    if not path.is_file():
        return None
    import cv2

    if cv2.haveImageReader(str(path)):
        return None
    quiet_ffmpeg()
    capture = cv2.VideoCapture(str(path))
    try:
        return path if capture.isOpened() else None
    finally:
        capture.release()


def read_video(source: Path | int, max_frames: int, quiet: bool) -> VideoFrames:
    """The frames of ``source`` the reconstruction takes
    (:func:`scene3D.multiview.video.select_frames`), each kept one and a summary line on
    stderr (the summary also with ``quiet``); :class:`UsageError` when fewer than two
    are kept."""
    quiet_ffmpeg()
    chosen = select_frames(
        read_frames(source, timed=True), max_frames=max_frames,
        stop_when_full=isinstance(source, int),
        progress=None if quiet else (lambda line: print(line, file=sys.stderr)))
    what = f"video '{source}'" if isinstance(source, Path) else f"camera {source}"
    if len(chosen.names) < 2:
        raise UsageError(f"{what}: {chosen.summary()}; a reconstruction needs two frames "
                         "that moved apart")
    print(f"{what}: {chosen.summary()}", file=sys.stderr)
    return chosen


def _output_folder(folder: Path) -> Path:
    """``folder``, made (and noted, so that a failed run removes it) when missing."""
    if not folder.exists():
        folder.mkdir()
        note_created_folders([folder])
    return folder


def write_frames(folder: Path, recon: MultiViewReconstruction, images: list[np.ndarray]
                 ) -> dict[str, Path]:
    """The frames of the views in a model as ``folder/NAME.png``; ``{name: path}``."""
    _output_folder(folder)
    placed = {v for model in recon.models for v in np.flatnonzero(model.registered)}
    return {recon.names[v]: write_png(folder / f"{recon.names[v]}.png", images[v])
            for v in sorted(placed)}


def write_undistorted(folder: Path, model: ColmapModel, images: dict[str, Path | np.ndarray]
                      ) -> tuple[ColmapModel, dict[str, Path]]:
    """The images of ``model`` (photos' paths or frames, by name) undistorted into
    ``folder`` (:func:`scene3D.io.undistorted.write_undistorted_images`): the pinhole model
    of the copies, and the copies by name."""
    return write_undistorted_images(_output_folder(folder), model, images)
