"""Two-view poses against a Strecha-format ground truth: the rows ``scene3d evaluate`` prints.

Each view of a pair is one engine task (its working image and features), each pair another
(matching, the two-view reconstruction or self-calibration, the errors against the truth);
:func:`evaluate_pairs` yields one row (a dict) per pair, and :func:`summarize_pair_rows`,
:func:`trust_line` and :func:`focal_summary` give the summary the command prints.
"""

from __future__ import annotations

import csv
import io
import logging
import math
import re
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..engines import Engine, Progress
from ..errors import ReconstructionError, plural
from ..features.matching import ImageFeatures, Matches, find_matches, image_features, match_features
from ..geometry.camera import adapt_intrinsics_to_size, scale_intrinsics_halved
from ..io.datasets import StrechaCamera, relative_pose
from ..io.images import load_working_image, read_image_size
from ..optim.uncertainty import pose_error_chi2
from ..twoview import TwoViewSettings, check_against_flow, reconstruct_from_matches
from .poses import relative_pose_error, sigma_calibration, summarize_pose_errors

logger = logging.getLogger(__name__)


def pairs_from_specs(specs: list[str], count: int) -> list[tuple[int, int]]:
    """The index pairs that ``specs`` select, in order.

    Parameters
    ----------
    specs : list of str
        ``"consecutive"`` (i, i+1), ``"skipN"`` (i, i+1+N) or ``"A-B"`` (indices).
    count : int
        The number of images the indices refer to.

    Returns
    -------
    list of (int, int)
        The pairs, in the order the specs give them.

    Raises
    ------
    ValueError
        A spec that is none of those, an index out of range, an image paired with itself, no
        pair at all, or a pair selected twice (``4-5 4-5``, or ``consecutive 4-5``): it would
        count twice in the summary.
    """
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
                raise ValueError(f"bad pair {spec!r}: use consecutive, skipN or A-B") from None
            if not (0 <= a < count and 0 <= b < count):
                raise ValueError(f"pair {spec!r} is out of range 0..{count - 1}")
            if a == b:
                raise ValueError(f"pair {spec!r} pairs an image with itself")
            selected = [(a, b)]
        for pair in selected:
            if pair in given_by:
                by = f" (by {given_by[pair]!r} and {spec!r})" if given_by[pair] != spec else ""
                raise ValueError(f"pair {pair[0]}-{pair[1]} is given twice{by}: list each pair "
                                 "once (it would count twice in the summary)")
            given_by[pair] = spec
        pairs += selected
    if not pairs:
        raise ValueError(f"no image pairs: {' '.join(specs)} selects none of the {count} images")
    return pairs


@dataclass(frozen=True)
class PairView:
    """What the pairs need of one view, computed once (one task per image).

    Attributes
    ----------
    shape : tuple[int, ...]
        ``(h, w, 3)`` of the working image.
    K : (3, 3) float64
        Intrinsics of the working image, from the view's camera file.
    features : ImageFeatures or None
        Keypoints and descriptors; None for the ``"flow"`` feature mode.
    image : (h, w, 3) uint8
        The working image: the flow check of each pair's pose
        (:func:`scene3D.twoview.check_against_flow`) and the flow mode's tracks
        need it.
    photo : (name, ExifCamera or None, (width, height)) or None
        Without the camera files' intrinsics (``no_calib``): what
        :func:`scene3D.geometry.intrinsics_prior.camera_prior` needs of the photo (its EXIF
        and stored size).
    """

    shape: tuple[int, ...]
    K: np.ndarray
    features: ImageFeatures | None
    image: np.ndarray
    photo: tuple | None = None


def load_pair_view(path: Path, camera: StrechaCamera, max_width: int | None,
               feature: str, no_calib: bool = False) -> PairView:
    """The working image of one view and its features (a task: see :func:`evaluate_pairs`).

    The camera file's ``K`` holds for its image size: a photo stored smaller (of the same
    aspect ratio) takes ``K`` scaled; another aspect ratio is an input error. With
    ``no_calib`` the camera file's distortion is not removed and the photo's EXIF and size
    are kept for the pair's focal-length prior.

    Parameters
    ----------
    path : Path
        The photo.
    camera : StrechaCamera
        Its ground-truth camera (``K`` and distortion for its stored size).
    max_width : int or None
        The working width's bound (halving), or None for the photo's size.
    feature : str
        A normalised feature mode (``"SIFT"``, ``"flow"``, ...).
    no_calib : bool, optional
        Keep the EXIF and size for a focal-length prior instead of using ``K``'s distortion.

    Returns
    -------
    PairView

    Raises
    ------
    ValueError
        The photo's aspect ratio is not its camera file's.
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
        return PairView(img.shape, K_working, None, img, photo)
    return PairView(img.shape, K_working, image_features(img, feature), img, photo)


def pair_matches(view_a: PairView, view_b: PairView) -> Matches:
    """The matches of two views: their descriptors matched, or optical-flow tracks.

    Parameters
    ----------
    view_a, view_b : PairView
        The pair's views, both with features or both without (flow).

    Returns
    -------
    Matches
    """
    if view_a.features is None:  # flow: tracks belong to the pair
        return find_matches(view_a.image, view_b.image, "flow")
    return match_features(view_a.features, view_b.features)


def unanswered_row(name: str, width: int) -> dict:
    """A row of the table before its pair is answered: what a refused pair keeps.

    Parameters
    ----------
    name : str
        The pair's name, ``"A.jpg-B.jpg"``.
    width : int
        The working width in pixels.

    Returns
    -------
    dict
        Infinite errors, no inliers, NaN sigmas and scales, flagged.
    """
    return {"pair": name, "width": width, "feature": "",
            "rotation_deg": np.inf, "translation_deg": np.inf, "inliers": 0, "points": 0,
            "rotation_sigma_deg": np.nan, "translation_sigma_deg": np.nan,
            "rotation_chi2": np.nan, "translation_chi2": np.nan,
            "focal_scale": np.nan, "behind_share": np.nan, "distortion_shift_deg": np.nan,
            "flagged": True, "note": ""}


def evaluate_pair(name: str, view_a: PairView, view_b: PairView,
                   truth: tuple[np.ndarray, np.ndarray], settings: TwoViewSettings) -> dict:
    """One row of the table: the pose errors of a pair against the true relative pose, or
    why it was refused (a task: see :func:`evaluate_pairs`).

    Parameters
    ----------
    name : str
        The pair's name.
    view_a, view_b : PairView
        Its views.
    truth : ((3, 3) float64, (3,) float64)
        The true ``R_cam2_from_cam1`` and ``t`` (:func:`scene3D.io.datasets.relative_pose`).
    settings : TwoViewSettings
        The two-view pipeline's settings.

    Returns
    -------
    dict
        The row: errors in degrees, sigmas, chi-square values, counts, ``flagged``, ``note``
        and ``seconds``.
    """
    t0 = time.perf_counter()
    row = unanswered_row(name, view_a.shape[1])
    try:
        if view_a.shape != view_b.shape or not np.allclose(view_a.K, view_b.K, rtol=1e-6,
                                                           atol=1e-6):
            row["note"] = "refused: the two views have different intrinsics or sizes " \
                          "(the two-view pipeline assumes one camera)"
            return row
        matches = pair_matches(view_a, view_b)
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


def evaluate_pair_no_calib(name: str, view_a: PairView, view_b: PairView,
                            truth: tuple[np.ndarray, np.ndarray],
                            settings: TwoViewSettings) -> dict:
    """One row without the camera files' intrinsics: the pair self-calibrates its focal length
    from its photos' EXIF or the default prior (:mod:`scene3D.selfcalibration`), and
    ``focal_scale`` is the focal length found over the camera file's (a task: see
    :func:`evaluate_pairs`).

    Parameters
    ----------
    name : str
        The pair's name.
    view_a, view_b : PairView
        Its views, loaded with ``no_calib``.
    truth : ((3, 3) float64, (3,) float64)
        The true ``R_cam2_from_cam1`` and ``t``.
    settings : TwoViewSettings
        The two-view pipeline's settings.

    Returns
    -------
    dict
        The row of :func:`evaluate_pair` with ``focal_error`` and ``calibration_source``.
    """
    from ..geometry.intrinsics_prior import CameraMismatchError, camera_prior
    from ..selfcalibration import self_calibrate_pair

    t0 = time.perf_counter()
    row = unanswered_row(name, view_a.shape[1]) | {"focal_error": np.nan,
                                                    "calibration_source": ""}
    try:
        try:
            prior = camera_prior([view_a.photo, view_b.photo])
        except ValueError as exc:  # two sizes, cameras or zoom settings
            problem = exc.problem if isinstance(exc, CameraMismatchError) else exc
            row["note"] = f"refused: {problem}"  # with the camera files' K, they serve
            return row
        for message in prior.warnings:
            logger.warning("%s", message)
        levels = round(math.log2(prior.image_size[0] / view_a.shape[1]))
        matches = pair_matches(view_a, view_b)
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

    Parameters
    ----------
    engine : Engine
        Runs the tasks (:mod:`scene3D.engines`).
    images : list of Path
        The dataset's photos, in order.
    cameras : list of StrechaCamera
        Their ground-truth cameras.
    pairs : list of (int, int)
        Index pairs into ``images`` (:func:`pairs_from_specs`).
    max_width : int or None
        The working width's bound, or None for the photos' size.
    feature : str
        A normalised feature mode.
    settings : TwoViewSettings
        The two-view pipeline's settings.
    progress : Progress, optional
        Told of the tasks done.
    no_calib : bool, optional
        Self-calibrate each pair from its photos' EXIF instead of using the camera files' K.

    Yields
    ------
    dict
        One row per pair (:func:`evaluate_pair`, :func:`evaluate_pair_no_calib`).
    """
    used = sorted({i for pair in pairs for i in pair})
    views = engine.map(load_pair_view, [(images[i], cameras[i], max_width, feature, no_calib)
                                    for i in used],
                       label="views", progress=progress)
    shared = {i: engine.share(view) for i, view in zip(used, views)}
    rows = engine.map(evaluate_pair_no_calib if no_calib else evaluate_pair,
                      [(f"{images[a].name}-{images[b].name}", shared[a], shared[b],
                        relative_pose(cameras[a], cameras[b]), settings) for a, b in pairs],
                      label="pairs", progress=progress)
    del shared, views  # a view is kept (here or on the cluster) while a pair needs it
    yield from rows


def focal_summary(rows: list[dict]) -> str:
    """The summary line without a calibration: focal errors against the camera files and
    their sources.

    Parameters
    ----------
    rows : list of dict
        Rows of :func:`evaluate_pair_no_calib`.

    Returns
    -------
    str
    """
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


def summarize_pair_rows(rows: list[dict]) -> dict:
    """What the summary lines say of the rows of :func:`evaluate_pairs`.

    Parameters
    ----------
    rows : list of dict
        The rows, one per pair.

    Returns
    -------
    dict
        ``stats`` (:func:`scene3D.evaluation.poses.summarize_pose_errors`), ``calibration``
        (:func:`scene3D.evaluation.poses.sigma_calibration`), ``widths`` (the working widths,
        ``"768"`` or ``"768/1536"``), ``features`` (the detectors that ran, ``""`` when no pair
        matched) and ``focal_scales`` (the matches' focal length over the camera files', of the
        pairs that fitted one).
    """
    return {
        "stats": summarize_pose_errors([r["rotation_deg"] for r in rows],
                                       [r["translation_deg"] for r in rows],
                                       [r["flagged"] for r in rows]),
        "calibration": sigma_calibration([r["rotation_chi2"] for r in rows],
                                         [r["translation_chi2"] for r in rows]),
        "widths": "/".join(str(w) for w in sorted({r["width"] for r in rows})),
        # The detector that ran (SIFT when SURF is not in this OpenCV build).
        "features": "/".join(sorted({r["feature"] for r in rows if r["feature"]})),
        "focal_scales": [r["focal_scale"] for r in rows if np.isfinite(r["focal_scale"])],
    }


def trust_line(stats: dict[str, float]) -> str:
    """The summary's line on the flags: right poses flagged, poses off and flagged.

    Parameters
    ----------
    stats : dict
        :func:`scene3D.evaluation.poses.summarize_pose_errors` of the rows.

    Returns
    -------
    str
    """
    return (f"Trust: {plural(int(stats['right_flagged']), 'right pose')} "
            f"(< 1 deg) flagged; {int(stats['off2_flagged'])} of "
            f"{plural(int(stats['off2']), 'pose')} "
            f"more than 2 deg off (or refused) flagged; {int(stats['wrong_unflagged'])} more "
            "than 5 deg off not flagged.")


def rows_csv_text(rows: list[dict]) -> str:
    """The rows as CSV text, a header of the first row's keys.

    Parameters
    ----------
    rows : list of dict
        At least one row.

    Returns
    -------
    str
    """
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue()
