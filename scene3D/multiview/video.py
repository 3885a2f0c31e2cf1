"""The frames of a video worth reconstructing: sharp, and far enough from each other.

A video has many more frames than a reconstruction wants: neighbours are nearly the
same view (no parallax between them, only more work), and some are blurred by the
motion. :func:`select_frames` reads named frames one at a time (e.g.
:func:`scene3D.calibration.views.read_frames` with ``timed=True``) and keeps

- no blurred frame: a frame's sharpness, the variance of its Laplacian, is compared
  with the median of its neighbours' (the ``sharpness_window`` frames around it, so a
  video's own texture and focus set the scale); below ``blur_ratio`` of it, the frame
  is blurred;
- the first sharp frame, then each sharp frame whose points moved from the last kept
  frame by ``min_motion`` of the image diagonal (the median displacement of corners
  tracked frame to frame with pyramidal Lucas-Kanade), or for which most tracks were
  lost (the view changed too fast to follow); a frame needs :data:`MIN_CORNERS` corners
  to track (a blank frame, a fade from black are not kept); and the last sharp frame when it moved
  half that from the frame kept before (the end of the video stays covered);
- at most ``max_frames``: from a file, when more frames qualify the kept ones are
  thinned to every other one and ``min_motion`` doubled, so the whole video stays
  covered at an even spacing; from a stream that never ends (a webcam,
  ``stop_when_full``), reading stops at ``max_frames``.

The motion is image motion, not a baseline: a camera turning on the spot moves the
image without parallax, and its frames are kept all the same (the reconstruction
then leaves out the views it cannot triangulate from).

Only the kept frames, and the few frames of the sharpness window, are in memory.
Images are BGR ``uint8`` as OpenCV reads them (:mod:`scene3D.geometry`).
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import cv2
import numpy as np

from ..calibration.views import frame_time_s
from ..errors import plural

logger = logging.getLogger(__name__)

#: The defaults of :func:`select_frames`.
MAX_FRAMES = 40
MIN_MOTION = 0.05
BLUR_RATIO = 0.5
SHARPNESS_WINDOW = 15
#: Corners are tracked on a copy at most this wide.
TRACK_WIDTH_PX = 640
#: A frame that keeps fewer than this share of the last kept frame's tracks is kept.
MIN_TRACKED_SHARE = 0.3
#: A frame with fewer corners than this to track (blank, a fade from black) is not kept.
MIN_CORNERS = 20


@dataclass(frozen=True)
class FrameChoice:
    """What :func:`select_frames` decided for one frame.

    Attributes
    ----------
    name : str
    kept : bool
        In the selection (a frame thinned out later says so in ``reason``).
    reason : str
        Why, in a few words: ``"first sharp frame"``, ``"moved 5.3 % of the diagonal"``,
        ``"blurred: sharpness 0.21 of its neighbours'"``, ``"moved only 1.2 % ..."``,
        ``"featureless: 3 corners to track"``, ``"thinned out: ..."``.
    motion : float
        The median displacement from the last kept frame, as a share of the image
        diagonal (NaN for the first and for blurred frames).
    sharpness : float
        Its Laplacian variance over the median of its neighbours'.
    """

    name: str
    kept: bool
    reason: str
    motion: float
    sharpness: float


@dataclass(frozen=True)
class VideoFrames:
    """The frames :func:`select_frames` kept, and why.

    Attributes
    ----------
    images : list of (H, W, 3) uint8
        The kept frames, in video order.
    names : list of str
        Their names, as the frames came.
    reasons : list of str
        Why each was kept.
    choices : tuple of FrameChoice
        Every frame read, in order (also the left-out ones).
    image_size : tuple[int, int]
        (width, height) of the frames.
    min_motion : float
        The spacing in the end (doubled by each thinning).
    """

    images: list[np.ndarray]
    names: list[str]
    reasons: list[str]
    choices: tuple[FrameChoice, ...]
    image_size: tuple[int, int]
    min_motion: float

    def counts(self) -> dict[str, int]:
        """How many frames were ``"read"``, ``"kept"``, ``"blurred"``, ``"close"`` (too
        little motion), ``"featureless"`` and ``"thinned"``."""
        out = {"read": len(self.choices), "kept": len(self.names), "blurred": 0,
               "close": 0, "featureless": 0, "thinned": 0}
        for choice in self.choices:
            for key in ("blurred", "featureless", "thinned"):
                if choice.reason.startswith(key):
                    out[key] += 1
            if choice.reason.startswith("moved only"):
                out["close"] += 1
        return out

    def summary(self) -> str:
        """One line: ``"60 frames read, 14 kept (spacing 5 % of the diagonal), 6 blurred,
        40 too close to the frame kept before"``."""
        n = self.counts()
        parts = [f"{plural(n['read'], 'frame')} read", f"{n['kept']} kept (spacing "
                 f"{100 * self.min_motion:.3g} % of the diagonal)"]
        if n["blurred"]:
            parts.append(f"{n['blurred']} blurred")
        if n["close"]:
            parts.append(f"{n['close']} too close to the frame kept before")
        if n["featureless"]:
            parts.append(f"{n['featureless']} without corners to track")
        if n["thinned"]:
            parts.append(f"{n['thinned']} thinned out to stay within the bound")
        return ", ".join(parts)

    def to_dict(self) -> dict:
        """The choice as JSON-ready data (the run's ``reconstruction.json``): the
        :meth:`summary` line, the :meth:`counts`, the spacing, the frame size, and each
        frame read, in order, with its name, its time in the video (``time_s``, None for
        a name that is no time), whether it was kept and why, its ``motion`` (None where
        NaN) and ``sharpness``."""
        return {"summary": self.summary(), "counts": self.counts(),
                "min_motion": self.min_motion, "image_size": list(self.image_size),
                "frames": [{"name": c.name, "time_s": frame_time_s(c.name), "kept": c.kept,
                            "reason": c.reason,
                            "motion": c.motion if np.isfinite(c.motion) else None,
                            "sharpness": c.sharpness} for c in self.choices]}


def sharpness(grey: np.ndarray) -> float:
    """The variance of the Laplacian of a grey ``(H, W) uint8`` image (higher: sharper).

    Parameters
    ----------
    grey : (H, W) uint8 ndarray
        A grey image.

    Returns
    -------
    float
    """
    return float(cv2.Laplacian(grey, cv2.CV_64F).var())


def _tracking_copy(grey: np.ndarray) -> np.ndarray:
    """``grey`` at most :data:`TRACK_WIDTH_PX` wide."""
    w = grey.shape[1]
    if w <= TRACK_WIDTH_PX:
        return grey
    scale = TRACK_WIDTH_PX / w
    return cv2.resize(grey, (TRACK_WIDTH_PX, round(grey.shape[0] * scale)),
                      interpolation=cv2.INTER_AREA)


def _corners(small: np.ndarray) -> np.ndarray:
    """Corners to track, ``(N, 1, 2) float32`` (OpenCV's layout, kept inside this module)."""
    found = cv2.goodFeaturesToTrack(small, maxCorners=400, qualityLevel=0.01,
                                    minDistance=max(4, small.shape[1] // 80))
    return np.empty((0, 1, 2), np.float32) if found is None else found.astype(np.float32)


def select_frames(
    frames: Iterable[tuple[str, np.ndarray]],
    *,
    max_frames: int = MAX_FRAMES,
    min_motion: float = MIN_MOTION,
    blur_ratio: float = BLUR_RATIO,
    sharpness_window: int = SHARPNESS_WINDOW,
    stop_when_full: bool = False,
    progress: Callable[[str], None] | None = None,
) -> VideoFrames:
    """Keep the sharp frames of a video that moved enough from the frame kept before.

    Parameters
    ----------
    frames : iterable of (str, (H, W, 3) uint8)
        Named frames in video order, all of one size (e.g.
        :func:`scene3D.calibration.views.read_frames` with ``timed=True``).
    max_frames : int
        The most frames kept (at least 2).
    min_motion : float
        The median image motion, as a share of the image diagonal, from the last kept
        frame that makes a frame worth keeping (0.05: 40 px in a 640x480 video).
    blur_ratio : float
        A frame whose Laplacian variance is below this share of the median of its
        ``sharpness_window`` neighbours' is blurred, and never kept (0.5: a frame with
        half the detail of the frames around it).
    sharpness_window : int
        How many frames around a frame (itself included) set its reference sharpness.
    stop_when_full : bool
        Stop reading at ``max_frames`` kept frames (a webcam, which never ends) rather
        than thin them out to cover the whole video.
    progress : callable, optional
        Called with ``"kept NAME: REASON"`` for each frame kept (default: logging at INFO).

    Returns
    -------
    VideoFrames

    Raises
    ------
    ValueError
        A bad parameter, no frame at all, or a frame of another size than the first.
    """
    if max_frames < 2:
        raise ValueError(f"`max_frames` must be at least 2, got {max_frames}")
    if not min_motion > 0 or not 0 < blur_ratio < 1 or sharpness_window < 1:
        raise ValueError("`min_motion` must be > 0, `blur_ratio` in (0, 1) and "
                         f"`sharpness_window` >= 1, got {min_motion}, {blur_ratio}, "
                         f"{sharpness_window}")
    say = progress or (lambda message: logger.info("%s", message))
    half = sharpness_window // 2
    window: deque[float] = deque(maxlen=sharpness_window)  # sharpness of frames around
    pending: deque[tuple[str, np.ndarray, np.ndarray, float]] = deque()
    choices: list[FrameChoice] = []
    kept: list[tuple[str, np.ndarray, str]] = []
    state: dict = {"size": None, "spacing": float(min_motion), "full": False}
    track: dict = {}  # the last kept frame's corners, where they are now, the previous grey

    def decide(name: str, image: np.ndarray, grey: np.ndarray, sharp: float,
               reference: float) -> None:
        ratio = sharp / reference if reference > 0 else 1.0
        if ratio < blur_ratio:
            choices.append(FrameChoice(name, False, f"blurred: sharpness {ratio:.2f} of its "
                                       "neighbours'", float("nan"), ratio))
            return
        small = _tracking_copy(grey)
        diagonal = float(np.hypot(*small.shape[::-1]))
        motion, reason = float("nan"), "first sharp frame"
        if kept:
            moved = track["start"]
            now, status, _ = cv2.calcOpticalFlowPyrLK(track["grey"], small, track["now"], None,
                                                      winSize=(21, 21), maxLevel=3)
            ok = status.ravel() == 1 if now is not None else np.zeros(len(moved), bool)
            track.update(start=moved[ok], now=now[ok] if now is not None else moved[ok],
                         grey=small)
            share = ok.sum() / max(track["count"], 1)
            if ok.sum():
                motion = float(np.median(np.linalg.norm(
                    track["now"] - track["start"], axis=2))) / diagonal
            last = kept[-1][0]
            if share < MIN_TRACKED_SHARE:
                reason = (f"lost {100 * (1 - share):.0f} % of the corners tracked from {last}: "
                          "the view changed")
            elif motion >= state["spacing"]:
                reason = f"moved {100 * motion:.1f} % of the diagonal from {last}"
            else:
                choices.append(FrameChoice(name, False, f"moved only {100 * motion:.1f} % of "
                                           f"the diagonal from {last}", motion, ratio))
                track["last"] = (len(choices) - 1, image)
                return
        corners = _corners(small)
        if len(corners) < MIN_CORNERS:
            choices.append(FrameChoice(name, False, f"featureless: {len(corners)} corners to "
                                       "track", motion, ratio))
            return
        track.update(start=corners, now=corners.copy(), grey=small, count=len(corners),
                     last=None)
        kept.append((name, image, reason))
        choices.append(FrameChoice(name, True, reason, motion, ratio))
        say(f"kept {name}: {reason}")
        if len(kept) > max_frames:
            _thin()
        if stop_when_full and len(kept) >= max_frames:
            state["full"] = True

    def _thin() -> None:
        """Every other kept frame out (the last one stays), the spacing doubled."""
        keep = set(range(0, len(kept), 2)) | {len(kept) - 1}
        out = {kept[i][0] for i in range(len(kept)) if i not in keep}
        kept[:] = [kept[i] for i in sorted(keep)]
        state["spacing"] *= 2
        for k, choice in enumerate(choices):
            if choice.name in out and choice.kept:
                choices[k] = FrameChoice(choice.name, False, "thinned out: more frames "
                                         f"moved enough than the {max_frames} kept",
                                         choice.motion, choice.sharpness)
        say(f"more than {max_frames} frames: every other one left out, now "
            f"{100 * state['spacing']:.3g} % of the diagonal apart")

    def decide_oldest() -> None:
        name, image, grey, sharp = pending.popleft()
        decide(name, image, grey, sharp, float(np.median(window)))

    for name, image in frames:
        image = np.asarray(image)
        size = (image.shape[1], image.shape[0])
        if state["size"] is None:
            state["size"] = size
        elif size != state["size"]:
            raise ValueError(f"'{name}' is {size[0]}x{size[1]}, not "
                             f"{state['size'][0]}x{state['size'][1]} like the first frame")
        grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        sharp = sharpness(grey)
        pending.append((name, image, grey, sharp))
        window.append(sharp)
        # A frame is decided once the window holds the frames after it too (at the start,
        # the first frames share the first window).
        while len(pending) > half and len(window) == window.maxlen and not state["full"]:
            decide_oldest()
        if state["full"]:
            break
    while pending and not state["full"]:
        decide_oldest()
    if not state["full"] and track.get("last") is not None:
        k, image = track["last"]  # the end of the video, when it moved half the spacing
        choice = choices[k]
        if choice.motion >= state["spacing"] / 2:
            reason = (f"the last sharp frame, moved {100 * choice.motion:.1f} % of the "
                      f"diagonal from {kept[-1][0]}")
            choices[k] = FrameChoice(choice.name, True, reason, choice.motion,
                                     choice.sharpness)
            kept.append((choice.name, image, reason))
            say(f"kept {choice.name}: {reason}")
            if len(kept) > max_frames:
                _thin()
    if state["size"] is None:
        raise ValueError("the video gave no frames")
    return VideoFrames([image for _, image, _ in kept], [name for name, _, _ in kept],
                       [reason for _, _, reason in kept], tuple(choices), state["size"],
                       state["spacing"])
