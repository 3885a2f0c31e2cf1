"""The views of a calibration: photos or video frames, and the board found in each.

- :func:`photo_files` lists the photos of a folder or a glob (no video among them);
- :func:`read_photos` reads them one at a time, all of one size (or the most common one),
  each photo once (a link, a copy or the same pixels saved again is refused: a view counted
  twice drags the calibration towards it);
- :func:`read_frames` reads the frames of a video file or a webcam (named by
  index or by time, :func:`frame_time_name`);
- :func:`collect_views` finds the board in each image
  (:func:`scene3D.calibration.board.detect_board`); from a video it keeps only views whose
  corners moved, until it has enough.

Only one image is in memory at a time unless the images are kept. Pixels as in
:mod:`scene3D.geometry`: images are BGR ``uint8`` as OpenCV reads them, sizes
``(width, height)``.
"""

from __future__ import annotations

import hashlib
import logging
import re
import time
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..geometry.conventions import image_size
from ..io.images import folder_images, glob_files, load_bgr, read_image_size
from ..io.paths import utf8_name_problem
from .board import BoardSpec, Detection, detect_board

logger = logging.getLogger(__name__)

#: From a video or a webcam: the distinct views to collect by default, and the fewest.
FRAMES = 20
MIN_FRAMES = 3
#: From a video or a webcam: a view counts as distinct when its corners moved by this
#: fraction of the image diagonal from every view kept.
MIN_MOTION = 0.05
#: Endings of video files, which are not photos (:func:`read_frames` reads them).
VIDEO_SUFFIXES = frozenset({".avi", ".mp4", ".m4v", ".mov", ".mkv", ".webm", ".wmv",
                            ".mpg", ".mpeg", ".flv", ".3gp", ".mts", ".m2ts"})


class ViewSourceError(ValueError):
    """Photos or a video that cannot give calibration views, with the reason.

    Attributes
    ----------
    reason : str
        ``"video_not_photos"`` (a video named as photos), ``"finds_video"`` (a pattern that
        matches a video), ``"mixed_sizes"`` (photos of several sizes), ``"folder_not_video"``
        (a folder named as a video).
    source : str
        The folder, glob or video as given.
    details : dict
        ``"video"`` (the video a pattern finds); ``"sizes"`` (``"640x480 (12), ..."``, most
        common first) and ``"turned"`` (some are stored turned by 90 degrees).
    """

    def __init__(self, reason: str, source: str, message: str, **details: object) -> None:
        self.reason = reason
        self.source = source
        self.details = details
        super().__init__(message)

    def __reduce__(self) -> tuple:
        return _rebuild_source_error, (self.reason, self.source, self.args[0], self.details)


def _rebuild_source_error(reason: str, source: str, message: str, details: dict
                          ) -> ViewSourceError:
    return ViewSourceError(reason, source, message, **details)


def photo_files(spec: str) -> list[Path]:
    """The photos of a folder (sorted, hidden files left out) or of a glob.

    Parameters
    ----------
    spec : str
        A folder, or a glob such as ``"calib/*.jpg"``.

    Returns
    -------
    list of Path

    Raises
    ------
    ValueError
        No image found, or a name that is not valid UTF-8.
    ViewSourceError
        ``spec`` is a video, or a glob that finds one.
    """
    path = Path(spec)
    files = folder_images(path) if path.is_dir() else glob_files(spec)
    if not files:
        raise ValueError(f"no images found in '{spec}'")
    videos = [p for p in files if p.suffix.lower() in VIDEO_SUFFIXES]
    if videos and path.is_file():  # named, not matched by a pattern
        raise ViewSourceError("video_not_photos", spec, f"'{spec}' is a video, not photos")
    if videos:
        raise ViewSourceError("finds_video", spec, f"'{spec}' finds '{videos[0]}', a video, "
                              "not a photo: narrow the pattern to the photos",
                              video=str(videos[0]))
    for file in files:
        problem = utf8_name_problem(file)
        if problem:
            raise ValueError(problem)
    return files


def read_photos(files: list[Path], skip_other_sizes: bool = False
                ) -> Iterator[tuple[str, np.ndarray]]:
    """The photos, one at a time, as ``(file name, BGR image)``.

    Sizes come from the file headers first, so that a folder of large photos is never
    held in memory at once.

    Parameters
    ----------
    files : list of Path
        The photos (:func:`photo_files`).
    skip_other_sizes : bool
        With photos of several sizes, keep those of the most common size (warned of)
        rather than refuse them.

    Yields
    ------
    name : str
    image : (H, W, 3) uint8

    Raises
    ------
    ViewSourceError
        ``"mixed_sizes"``, unless ``skip_other_sizes``.
    ValueError
        A photo given twice: the same file contents, or the same pixels.
    """
    sizes = {path: read_image_size(path) for path in files}
    counts = Counter(sizes.values())
    if len(counts) > 1:
        listing = ", ".join(f"{w}x{h} ({n})" for (w, h), n in counts.most_common())
        turned = any((h, w) in counts for w, h in counts if w != h)
        if not skip_other_sizes:
            raise ViewSourceError(
                "mixed_sizes", ", ".join(map(str, files)),
                f"the images have different sizes: {listing}; one calibration holds for one "
                "size (skip_other_sizes=True keeps the most common)"
                + ("; some are stored turned by 90 degrees (their pixels are read as stored, "
                   "whatever their EXIF orientation says)" if turned else ""),
                sizes=listing, turned=turned)
        keep = counts.most_common(1)[0][0]
        skipped = [path.name for path in files if sizes[path] != keep]
        logger.warning("skipping %d image(s) not %dx%d: %s", len(skipped), *keep,
                       ", ".join(skipped))
        files = [path for path in files if sizes[path] == keep]
    check_distinct_files(files)
    by_pixels: dict[bytes, Path] = {}
    for path in files:
        img = load_bgr(path)
        digest = hashlib.blake2b(img.tobytes(), digest_size=16)
        digest.update(repr(img.shape).encode())
        first = by_pixels.setdefault(digest.digest(), path)
        if first != path:  # e.g. one photo saved again as PNG
            raise ValueError(f"photo given twice: '{first}' and '{path}' (the same pixels)")
        yield path.name, img


def check_distinct_files(files: list[Path]) -> None:
    """Refuse one photo given twice (a link to it, a copy).

    Parameters
    ----------
    files : list of Path

    Raises
    ------
    ValueError
        Two of ``files`` have the same contents (named in the message).
    """
    by_content: dict[bytes, Path] = {}
    for path in files:
        digest = hashlib.blake2b(path.read_bytes(), digest_size=16).digest()
        first = by_content.setdefault(digest, path)
        if first != path:
            raise ValueError(f"photo given twice: '{first}' and '{path}'")


def read_frames(source: Path | int, timed: bool = False) -> Iterator[tuple[str, np.ndarray]]:
    """The frames of a video file or a webcam, one at a time, as ``("frame i", image)``.

    Parameters
    ----------
    source : Path or int
        A video file, or a camera index (``0``: the first webcam).
    timed : bool
        Name the frames by their time instead (:func:`frame_time_name`): their time
        stamp in the video, or for a camera the time since its first frame.

    Yields
    ------
    name : str
        ``"frame 0"``, ``"frame 1"``, ...; with ``timed`` ``"t000.00s"``, ``"t000.04s"``, ...
    image : (H, W, 3) uint8

    Raises
    ------
    ViewSourceError
        ``"folder_not_video"``: ``source`` is a folder.
    FileNotFoundError
        No such video file.
    ValueError
        OpenCV cannot open the video or the camera.
    """
    if isinstance(source, int):
        if source >= 2**31:  # OpenCV takes a C int, and raises on more
            raise ValueError(f"cannot open camera {source}: no such camera index")
        capture, what = cv2.VideoCapture(source), f"camera {source}"
    else:
        source = Path(source)
        if source.is_dir():
            raise ViewSourceError("folder_not_video", str(source),
                                  f"'{source}' is a folder, not a video file")
        if not source.is_file():
            raise FileNotFoundError(f"video not found: '{source}'")
        capture, what = cv2.VideoCapture(str(source)), f"video '{source}'"
    if not capture.isOpened():
        raise ValueError(f"cannot open {what}")
    index, fps, started = 0, capture.get(cv2.CAP_PROP_FPS), time.monotonic()
    try:
        while True:
            ok, frame = capture.read()
            if not ok:
                return
            if not timed:
                yield f"frame {index}", frame
            elif isinstance(source, int):
                yield frame_time_name(time.monotonic() - started), frame
            else:  # the frame's time stamp; from its index where the container has none
                msec = capture.get(cv2.CAP_PROP_POS_MSEC)
                seconds = msec / 1000 if msec > 0 or index == 0 or not fps > 0 else index / fps
                yield frame_time_name(seconds), frame
            index += 1
    finally:
        capture.release()


def frame_time_name(seconds: float) -> str:
    """A frame's name from its time in the video: ``12.4`` -> ``"t012.40s"``.

    Parameters
    ----------
    seconds : float

    Returns
    -------
    str
    """
    return f"t{max(seconds, 0.0):06.2f}s"


def frame_time_s(name: str) -> float | None:
    """The time in seconds a frame's name (:func:`frame_time_name`) gives:
    ``"t012.40s"`` -> ``12.4``; None for another name (``"frame 3"``, a photo's).

    Parameters
    ----------
    name : str

    Returns
    -------
    float or None
    """
    match = re.fullmatch(r"t(\d+\.\d+)s", name)
    return float(match.group(1)) if match else None


@dataclass(frozen=True)
class CollectedViews:
    """What :func:`collect_views` found.

    Attributes
    ----------
    views : list of Detection
    images : list of (H, W, 3) uint8
        The images of ``views`` (only with ``keep_images``, otherwise empty).
    image_size : tuple[int, int]
        (width, height) of every view.
    seen : int
        Photos or frames read.
    not_distinct : int
        Video/webcam frames with the board that were dropped because its corners had
        moved less than ``min_motion`` from a view already kept.
    without_board : tuple of str
        The images in which the board was not found.
    frames : int or None
        From a stream, the distinct views asked for; None for photos.
    """

    views: list[Detection]
    images: list[np.ndarray]
    image_size: tuple[int, int]
    seen: int
    not_distinct: int = 0
    without_board: tuple[str, ...] = ()
    frames: int | None = None

    @property
    def ended_early(self) -> bool:
        """A stream ended before giving the ``frames`` distinct views asked for."""
        return self.frames is not None and len(self.views) < self.frames


def is_distinct(det: Detection, kept: list[Detection], min_motion_px: float) -> bool:
    """Whether the board's corners in ``det`` moved by ``min_motion_px`` (mean, pixels) from
    each view of ``kept`` with the same corners.

    Parameters
    ----------
    det : Detection
    kept : list of Detection
    min_motion_px : float

    Returns
    -------
    bool
    """
    for other in kept:
        if other.image_points.shape == det.image_points.shape:
            motion = np.linalg.norm(other.image_points - det.image_points, axis=1).mean()
            if motion < min_motion_px:
                return False
    return True


def collect_views(images: Iterable[tuple[str, np.ndarray]], board: BoardSpec, *,
                  frames: int | None = None, min_motion: float = MIN_MOTION,
                  keep_images: bool = False,
                  progress: Callable[[str], None] | None = None) -> CollectedViews:
    """Detect the board in every photo, or in a stream's frames until ``frames`` distinct views.

    Parameters
    ----------
    images : iterable of (str, (H, W, 3) uint8)
        Named images (:func:`read_photos`, :func:`read_frames`), all of one size.
    board : BoardSpec
    frames : int, optional
        None for photos: every image with the board is a view. An int for a video or a
        webcam: a view must have moved by ``min_motion`` from those kept, and reading
        stops after ``frames`` views.
    min_motion : float
        With ``frames``: the motion of the corners, as a fraction of the image diagonal,
        that makes a view distinct.
    keep_images : bool
        Keep the images of the views (for undistorted copies); otherwise only one image
        is in memory at a time.
    progress : callable, optional
        With ``frames``: called with ``"view k/frames from frame i"`` for each view kept.

    Returns
    -------
    CollectedViews
        Perhaps fewer than the three views a calibration needs: the counts say why.

    Raises
    ------
    ValueError
        No image at all, or one of another size than the first.
    """
    views: list[Detection] = []
    kept_images: list[np.ndarray] = []
    size, seen, without_board, not_distinct = None, 0, [], 0
    for name, img in images:
        seen += 1
        if size is None:
            size = image_size(img)
        elif image_size(img) != size:
            raise ValueError(f"'{name}' is {image_size(img)}, not {size} like the first view")
        det = detect_board(img, board, name)
        if det is None:
            logger.info("%s: board not found", name)
            without_board.append(name)
            continue
        if frames is not None:
            if not is_distinct(det, views, min_motion * float(np.hypot(*size))):
                not_distinct += 1
                continue
            if progress is not None:
                progress(f"view {len(views) + 1}/{frames} from {name}")
        else:
            logger.info("%s: %d corners (%s)", name, len(det.image_points), det.method)
        views.append(det)
        if keep_images:
            kept_images.append(img)
        if frames is not None and len(views) >= frames:
            break
    if size is None:
        raise ValueError("the source gave no images")
    return CollectedViews(views, kept_images, size, seen, not_distinct, tuple(without_board),
                          frames)
