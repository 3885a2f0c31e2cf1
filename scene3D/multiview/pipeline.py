"""``reconstruct_views``: the stages in order, the independent ones through an engine.

Features (one task per image) and pair verification (one task per pair) run through
an :class:`scene3D.engines.Engine`; vocabulary, pair selection, tracks, registration,
triangulation and bundle adjustment stay here.

Views are processed in an order fixed by their content (a digest of each view's
keypoints and descriptors), not by their names or input order: the same photos under
other names give the same reconstruction. Only sequential pairs (``pairs="sequential"``, and
``"auto"`` when the images themselves say the input order is a sequence) use the input order.
Every per-view array of the result follows the input order.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ..engines import Engine, LocalEngine
from ..engines.timing import StageTimer
from ..errors import ReconstructionError, plural
from ..geometry.camera import (
    different_sizes_message,
    scale_intrinsics_halved,
    validate_distortion,
    validate_intrinsics,
)
from ..geometry.intrinsics_prior import FocalPrior
from ..geometry.lens import (
    corner_shifts_px,
    folds_within,
    max_shift_px,
    radial_coefficients,
    rescaled_coefficients,
)
from ..io.images import (
    BOOK_MAX_WIDTH_PX,
    ImageSource,
    bgr_order,
    folder_images,
    glob_files,
    source_label,
)
from .camera_passes import Attempt, CameraViews, camera_passes
from .cameras import (
    CameraPass,
    reference_camera,
    reference_features,
)
from .features import content_key, view_features
from .focal import FocalSettings
from .inputs import (  # noqa: F401 - default_focal_prior, default_camera_priors: public here too
    check_distinct_names,
    check_distinct_photos,
    check_K_for_size,
    default_camera_priors,
    default_focal_prior,
    too_few_keypoints,
)
from .lens import pair_lens_guess, refine_lens, undistorted_features
from .mapper import reconstruct_models
from .matching import match_and_verify_pair
from .models import MultiViewReconstruction
from .pairs import select_pairs
from .results import cameras_result, to_input_order
from .retrieval import describe_view, similarity_ranking, train_vocabulary
from .settings import SfMSettings
from .sfm_model import FocalEstimate
from .view_data import PairMatches, ViewFeatures

logger = logging.getLogger(__name__)


def image_sources(images: str | os.PathLike | Sequence[ImageSource | str]
                  ) -> list[ImageSource]:
    """The images ``images`` names, in order: a folder gives its images (sorted, names
    starting with '.' left out: :func:`scene3D.io.images.folder_images`), a path that is
    neither file nor folder is read as a glob (its files, sorted), a file and an array
    stay as they are; one path or a sequence of them (and of arrays).

    Parameters
    ----------
    images : path or sequence of path or (H, W, 3) uint8 ndarray
        A folder, a glob pattern, a file, or a sequence of files and BGR arrays.

    Returns
    -------
    list of path or ndarray


    Raises
    ------
    FileNotFoundError
        A folder without images, or a path that names nothing and matches no file.
    """
    items = [images] if isinstance(images, (str, os.PathLike)) else list(images)
    out: list[ImageSource] = []
    for item in items:
        if not isinstance(item, (str, os.PathLike)):
            out.append(item)
            continue
        path = Path(item)
        if path.is_dir():
            found = folder_images(path)
            if not found:
                raise FileNotFoundError(f"no image in folder '{path}'")
            out += found
        elif path.is_file():
            out.append(path)
        else:
            found = glob_files(os.fspath(item))
            if not found:
                raise FileNotFoundError(f"no image matches '{os.fspath(item)}' (neither a "
                                        "file, nor a folder, nor a glob that matches one)")
            out += found
    return out


def reconstruct_views(
    images: str | os.PathLike | Sequence[ImageSource | str],
    K: ArrayLike | None,
    dist: ArrayLike | None = None,
    *,
    max_width: int | None = 2 * BOOK_MAX_WIDTH_PX,
    names: Sequence[str] | None = None,
    feature: str = "SIFT",
    pairs: str = "auto",
    settings: SfMSettings | None = None,
    progress: Callable[[str], None] | None = None,
    engine: Engine | None = None,
    focal_prior: FocalPrior | None = None,
    camera_model: str = "auto",
    camera_mode: str = "auto",
    rgb: bool = False,
) -> MultiViewReconstruction:
    """Reconstruct cameras and points from several photos, calibrated or not, of one camera
    or of several.

    Parameters
    ----------
    images : path, glob, or sequence of paths, globs and (H, W[, C]) arrays
        Photos in any order (of one size with ``K``; without, each size is a camera of
        its own: ``camera_mode``), given as ``reconstruct-views`` takes them: a folder
        (its images, sorted; hidden names starting with '.' left out), a glob such as
        ``"photos/*.jpg"`` (its files, sorted), an image file, or a list
        of any of these and of BGR arrays (:func:`image_sources`).
    K : (3, 3) array_like or None
        Intrinsics of the **native** (stored) images; one that cannot be theirs (a
        ``K`` for larger photos: :func:`scene3D.geometry.camera.check_intrinsics_for_size`)
        is refused. None for photos without a calibration: one focal length (the
        principal point at the centre, no distortion) starts from ``focal_prior``
        and is refined by the photos
        (:mod:`scene3D.multiview.focal`); the result's ``K`` is the one found, its
        ``calibration_source`` and ``focal`` say how.
    dist : array_like, optional
        OpenCV distortion coefficients; the images are undistorted first (with ``K``
        only).
    max_width : int or None
        Halve while wider than this (default 2400: 3072 -> 1536);
        None keeps the native size. The result's ``K`` is for the working size.
    names : sequence of str, optional
        Names for the result and the report, distinct (default: file names, or view0,
        view1, ...).
    feature : str
        Detector (:data:`scene3D.features.FEATURE_MODES`, not ``"flow"``).
    pairs : str
        ``"auto"``, ``"retrieval"``, ``"sequential"`` or ``"all"``
        (:func:`scene3D.multiview.pairs.select_pairs`).
    settings : SfMSettings, optional
    progress : callable, optional
        Called with one line of text per step (default: logging at INFO).
    engine : Engine, optional
        Where feature extraction and pair verification run (default: in this process,
        :class:`scene3D.engines.LocalEngine`).
    focal_prior : FocalPrior, optional
        Without ``K``: the focal length to start from, of the native images (default:
        :func:`scene3D.io.exif.read_camera_prior` of the files, the EXIF focal length or
        1.2 times the longer side; for arrays the default).
    camera_model : str
        Without ``K``: ``"simple_radial"`` (one focal length and one radial coefficient,
        the default, ``"auto"``), ``"radial"`` (two coefficients) or ``"pinhole"`` (no
        distortion); the distortion is found from the largest model and the views
        reconstructed again with their keypoints undistorted (:mod:`scene3D.multiview.lens`).
        With ``K`` the calibration gives the camera: ``"auto"`` or ``"pinhole"`` only
        (``dist`` undistorts the images first).
    camera_mode : str
        Without ``K`` and ``focal_prior``: how the photos are grouped into cameras
        (:func:`scene3D.geometry.intrinsics_prior.camera_groups`): ``"auto"`` (one
        camera per EXIF make, model, focal length and image size), ``"single"`` (one
        camera; photos that cannot share one are refused) or ``"per_photo"``. Each
        camera has its own focal length and lens (:mod:`scene3D.multiview.cameras`);
        the result's ``view_camera`` and ``cameras`` say which and what.
    rgb : bool
        The arrays among ``images`` are RGB (PIL, imageio); by default they are BGR, as
        cv2 loads them (:func:`scene3D.io.images.bgr_order`). Files are read as they are.

    Returns
    -------
    MultiViewReconstruction
        One model, or several when parts of the view graph cannot be joined; check
        ``ok`` (every model passed the consistency check and has
        ``SfMSettings.min_model_points`` points) and ``unregistered_reasons``.

    Raises
    ------
    ReconstructionError
        Fewer than two views, no pair gives a trustworthy start (the message says so
        when the images have too few keypoints for any pair), or the consistency check
        took so many views out of the first model that none could be kept (reason
        ``"no_model"``; usually a calibration that does not fit).
    FileNotFoundError
        A path that is neither a file nor a folder and a glob that matches no file, or a
        folder without images.
    FileNotFoundError, ValueError
        Unreadable images, images of different sizes with ``K`` (or ``camera_mode``
        ``"single"``), one photo given twice (a copy), two views of one name (``names``,
        by default the file names), a ``K`` (or ``focal_prior``) for another image size
        than the images' native one; with ``camera_mode`` ``"single"``, photos from
        different cameras (EXIF make and model, or focal length).
    """
    s = settings or SfMSettings()
    engine = engine or LocalEngine()
    say = progress or (lambda message: logger.info("%s", message))
    images = [bgr_order(source, rgb) for source in image_sources(images)]
    if names is None:
        names = [Path(src).name if isinstance(src, (str, os.PathLike)) else f"view{i}"
                 for i, src in enumerate(images)]
    names = tuple(names)
    check_distinct_names(images, names)
    if len(images) < 2:
        raise ReconstructionError("too_few_views", "need at least two images",
                                  views=len(images))
    if camera_model == "auto":
        camera_model = "pinhole" if K is not None else "simple_radial"
    num_radial = radial_coefficients(camera_model)
    if K is not None and num_radial:
        raise ValueError(f"camera_model {camera_model!r} needs photos without a calibration: "
                         "with `K` the calibration gives the camera (its `dist` undistorts "
                         "the images)")
    if K is None:
        if dist is not None:
            raise ValueError("`dist` needs `K`: photos without a calibration are taken as "
                             "undistorted")
        if focal_prior is None:
            view_camera, priors = default_camera_priors(images, names, camera_mode)
        else:
            view_camera, priors = np.zeros(len(images), dtype=int), [focal_prior]
        cameras = priors if len(priors) > 1 else None
        focal_prior = priors[reference_camera(view_camera)]
        K = focal_prior.K
    else:
        focal_prior = cameras = None
        view_camera = np.zeros(len(images), dtype=int)
    K_native = validate_intrinsics(K)
    dist = validate_distortion(dist)
    timer = StageTimer()  # seconds per stage; the mapper's stages add to it

    with timer.stage("features"):
        found = list(engine.map(view_features,
                                [(src, K_native if cameras is None else cameras[c].K, dist,
                                  max_width, name, feature)
                                 for src, name, c in zip(images, names, view_camera)],
                                label="features"))
        labels = [source_label(src, name) for src, name in zip(images, names)]
        # Each camera's views share its size (one camera: all of them).
        lead = [int(np.flatnonzero(view_camera == c)[0]) for c in range(view_camera.max() + 1)]
        for (_, size, _, _), label, c in zip(found, labels, view_camera):
            first = found[lead[c]][1]
            if size != first:
                raise ValueError(different_sizes_message(label, size, labels[lead[c]], first))
        reference = lead[reference_camera(view_camera)]
        first = found[reference][1]
        check_K_for_size(K_native, first, focal_prior)
        working_size, levels = found[reference][2], found[reference][3]
        K_work = scale_intrinsics_halved(K_native, levels)
        if cameras is not None:  # each camera at its working size (scene3D.multiview.cameras)
            K_cameras = np.stack([scale_intrinsics_halved(prior.K, found[v][3])
                                  for prior, v in zip(cameras, lead)])
            camera_sizes = [found[v][2] for v in lead]
        focal = None if focal_prior is None else FocalSettings(
            float(K_work[0, 0]), focal_prior.sigma_log, focal_prior.source)
    say(f"features: {', '.join(str(len(f[0].keypoints)) for f in found)} keypoints")

    # Canonical order: by content, so that names and input order change nothing.
    keys = [content_key(f[0]) for f in found]
    check_distinct_photos(keys, [len(f[0].keypoints) for f in found], labels)
    order = np.array(sorted(range(len(found)), key=lambda v: (keys[v], v)), dtype=int)
    position = np.empty_like(order)
    position[order] = np.arange(len(order))
    features: list[ViewFeatures] = [found[v][0] for v in order]
    canonical_names = [names[v] for v in order]
    canonical_camera = None if cameras is None else view_camera[order]
    if cameras is not None:
        camera_keypoints = [f.keypoints for f in features]
        raw_sizes = [f.sizes for f in features]
        used = CameraPass(K_cameras, np.zeros((len(cameras), num_radial)),
                          np.zeros(len(cameras), dtype=bool))
        features = reference_features(features, camera_keypoints, raw_sizes,
                                      canonical_camera, used.K, used.k, K_work)
        say(f"{len(cameras)} cameras: " + "; ".join(
            f"{prior.camera_name or 'camera'} {prior.image_size[0]}x{prior.image_size[1]} "
            f"({plural(int(np.sum(view_camera == c)), 'view')}, f {prior.focal_px:.0f} px from "
            f"{prior.source})" for c, prior in enumerate(cameras)))

    with timer.stage("retrieval"):
        vocabulary = train_vocabulary(features, s.vocabulary_words)
        described = list(engine.map(describe_view, [(f, vocabulary, s.probe_words)
                                                    for f in features], label="retrieval"))
        features = [dataclasses.replace(f, words=w) for f, (w, _) in zip(features, described)]
        ranking, _ = similarity_ranking(np.array([vlad for _, vlad in described]))

    with timer.stage("matching"):
        pair_list, selection = select_pairs(len(features), pairs, s.neighbours, ranking,
                                            s.retrieval_neighbours, sequence=position)
        handles = [engine.share(f) for f in features]
        num_words = vocabulary.size if not vocabulary.binary else 0

    latest_pairs: list[PairMatches] = []  # the last pass's verified pairs
    putative: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}  # of every pass

    def reconstruct_with(K_work: np.ndarray, start_from: FocalEstimate | None = None,
                         known_cameras: np.ndarray | None = None
                         ) -> Attempt:
        """The models under ``K_work``, the reasons for the views left out, the number of
        pairs matched and the pairs verified, ``(i, j, inliers)`` in the views' order: pair
        verification depends on ``K``."""
        with timer.stage("matching"):
            matched = {(i, j) for i, j in pair_list}

            def verify(batch: list[tuple[int, int]], label: str) -> list[PairMatches]:
                results = engine.map(match_and_verify_pair, [
                    (handles[i], handles[j], K_work, s, i, j, num_words, putative.get((i, j)))
                    for i, j in batch], label=label)
                found = []
                for (i, j), (matches, pair) in zip(batch, results):
                    putative[i, j] = matches
                    if pair is not None:
                        found.append(pair)
                return found

            verified = verify(pair_list, "pairs")
            latest_pairs[:] = verified
        say(f"{len(verified)} of {len(pair_list)} pairs verified ({selection})")

        def more_pairs(view: int, model_views: Sequence[int]) -> list[PairMatches]:
            """The view's next most similar model views it was not matched with yet."""
            inside = set(model_views)
            batch = []
            for other in ranking[view]:
                key = (min(view, int(other)), max(view, int(other)))
                if int(other) in inside and key not in matched:
                    batch.append(key)
                    if len(batch) == s.retry_candidates:
                        break
            matched.update(batch)
            new = verify(batch, "more pairs")
            verified.extend(new)
            return new

        try:
            models, reasons, _ = reconstruct_models(
                features, verified, K_work, s, more_pairs, say, canonical_names, focal,
                start_from, canonical_camera, known_cameras, timer=timer)
        except ReconstructionError as exc:
            few = too_few_keypoints(found, labels, s.min_pair_inliers, working_size)
            if exc.reason != "no_initial_pair" or few is None:
                raise
            raise ReconstructionError(exc.reason, few, **exc.counts) from None
        edges = [(p.i, p.j, p.num_inliers) for p in verified]
        return models, reasons, len(matched), edges

    lens, K_lens, lens_passes = np.zeros(num_radial), K_work.copy(), 0
    raw_keypoints = [f.keypoints for f in features]
    try:
        models, reasons, num_matched, verified_edges = reconstruct_with(
            K_work, known_cameras=None if cameras is None else used.known)
    except ReconstructionError as exc:
        # A lens that bends the matches can leave no pair trustworthy in the pinhole
        # geometry, or make the consistency check take right poses out of the first
        # model: undistort with the lens the best pairs call for and start again.
        guess = (pair_lens_guess(latest_pairs, features, K_work)
                 if exc.reason in ("no_initial_pair", "no_model") and focal is not None
                 and num_radial else None)
        if guess is None or folds_within(K_lens, [guess], working_size) or (
                cameras is not None and any(folds_within(K_c, [guess], size) for K_c, size
                                            in zip(used.K, camera_sizes))):
            raise
        say(f"no model with the keypoints as photographed ({exc}); the pairs with most "
            f"matches call for a lens with k1 {guess:+.3f}: starting again with them "
            "undistorted")
        if cameras is None:
            lens[0] = guess
            features = undistorted_features(features, raw_keypoints, K_lens, lens)
        else:  # every camera's first lens: k1 is of normalised coordinates, which the
            # reference pixels keep (scene3D.multiview.cameras)
            k = np.zeros_like(used.k)
            k[:, 0] = guess
            used = dataclasses.replace(used, k=k)
            features = reference_features(features, camera_keypoints, raw_sizes,
                                          canonical_camera, used.K, used.k, K_work)
        handles = [engine.share(f) for f in features]
        try:
            models, reasons, num_matched, verified_edges = reconstruct_with(
                K_work, known_cameras=None if cameras is None else used.known)
        except ReconstructionError:
            raise exc from None
        lens_passes = 1
    refits: list[float] = []
    # With a calibration file: views that refute its focal length are reconstructed
    # again with the one they call for, since a wrong focal length bends the cameras
    # (docs/benchmarks.md#a-calibration-the-views-refute). A pass that finds no model
    # keeps the last one, which fails its check.
    while (focal is None and models[0].check.focal_mismatch
           and len(refits) < s.max_focal_refits):
        scale = models[0].check.focal_scale
        K_refit = K_work @ np.diag([scale, scale, 1.0])
        say(f"the views fit a focal length {scale:.3f} times the one used: reconstructing "
            "them with it")
        try:
            models, reasons, num_matched, verified_edges = reconstruct_with(K_refit)
        except ReconstructionError as exc:
            say(f"no model with it either ({exc})")
            break
        refits.append(scale)
        K_work = K_refit
    # Without a calibration: the lens the largest model calls for, its keypoints
    # undistorted with it and the views reconstructed again (scene3D.multiview.lens).
    while cameras is None and focal is not None and num_radial and lens_passes < s.max_lens_passes:
        with timer.stage("lens"):
            K_model = models[0].K if models[0].K is not None else K_work
            fit = refine_lens(models[0], K_model, lens, K_lens, focal)
            current = rescaled_coefficients(lens, float(K_lens[0, 0]), float(K_model[0, 0]))
            moved = float(np.max(np.linalg.norm(
                corner_shifts_px(fit.K, fit.k, working_size)
                - corner_shifts_px(K_model, current, working_size), axis=1)))
        shift = max_shift_px(fit.K, fit.k, working_size)
        negligible = shift <= s.min_lens_shift * float(np.hypot(*working_size))
        if moved <= s.lens_tolerance_px or (negligible and not lens_passes):
            break
        if folds_within(fit.K, fit.k, working_size):  # no lens of a photo: a wrong fit
            say(f"the lens the model calls for (k {np.round(fit.k, 3).tolist()}) folds over "
                "inside the image: keeping the last")
            break
        say(f"lens distortion: k1 {fit.k[0]:+.3f} moves the image corners "
            f"{shift:.1f} px; reconstructing with the "
            "keypoints undistorted")
        kept = features, handles
        features = undistorted_features(features, raw_keypoints, fit.K, fit.k)
        handles = [engine.share(f) for f in features]
        # The focal length is known from the model now: no pair is self-calibrated again.
        start_from = None if models[0].focal is None else dataclasses.replace(
            models[0].focal, start_focal_px=float(fit.K[0, 0]))
        try:
            attempt = reconstruct_with(fit.K, start_from)
        except ReconstructionError as exc:
            attempt, why = None, str(exc)
        else:
            why = "it registers fewer views"
            if attempt[0][0].registered.sum() >= models[0].registered.sum():
                models, reasons, num_matched, verified_edges = attempt
                lens, K_lens, lens_passes = fit.k, fit.K, lens_passes + 1
                continue
        say(f"no better model with the keypoints undistorted ({why}): keeping the last")
        features, handles = kept
        break
    # Several cameras: each camera's focal length and lens the largest model calls for,
    # its keypoints mapped with them and the views reconstructed again
    # (scene3D.multiview.camera_passes), as for one camera's lens above.
    if cameras is not None:
        def reconstruct_from(K: np.ndarray, new_features: list[ViewFeatures],
                             start_from: FocalEstimate | None, known: np.ndarray) -> Attempt:
            """:func:`reconstruct_with` on ``new_features``, shared with the engine."""
            nonlocal features, handles
            features = new_features
            handles = [engine.share(f) for f in features]
            return reconstruct_with(K, start_from, known)

        views = CameraViews(canonical_camera, camera_keypoints, raw_sizes, K_cameras[:, 0, 0],
                            [prior.sigma_log for prior in cameras], camera_sizes)
        (models, reasons, num_matched, verified_edges), used, K_work, lens_passes = camera_passes(
            (models, reasons, num_matched, verified_edges), reconstruct_from, features, views,
            used, K_work, lens_passes, num_radial, s, say, timer)
    timings = timer.seconds
    timings["total"] = timer.total_s
    edges = tuple(sorted((int(min(order[i], order[j])), int(max(order[i], order[j])), int(n))
                         for i, j, n in verified_edges))  # in the input order
    if cameras is not None:
        return cameras_result(models, used, K_work, canonical_camera, order, reasons,
                               dict(names=names, pair_selection=selection,
                                    matched_pairs=num_matched, verified_pairs=len(edges),
                                    verified_edges=edges,
                                    timings_s=timings, feature=feature,
                                    min_model_points=s.min_model_points,
                                    camera_model=camera_model, lens_passes=lens_passes),
                               cameras, view_camera, camera_sizes)
    if focal is not None:
        K_work = models[0].K if models[0].K is not None else K_work
    if lens_passes:  # the lens about the final K: OpenCV's (k1, k2, p1, p2)
        k = rescaled_coefficients(lens, float(K_lens[0, 0]), float(K_work[0, 0]))
        dist = np.concatenate([k, np.zeros(4 - k.size)])
    return MultiViewReconstruction(
        names=names, K=np.asarray(K_work, np.float64), image_size=working_size,
        models=tuple(to_input_order(m, order) for m in models),
        unregistered_reasons={names[order[v]]: why for v, why in sorted(
            reasons.items(), key=lambda item: order[item[0]])},
        pair_selection=selection, matched_pairs=num_matched, verified_pairs=len(edges),
        verified_edges=edges,
        timings_s=timings,
        calibration_source="file" if focal is None else models[0].focal.source,
        prior_description="" if focal_prior is None else focal_prior.description,
        focal_refits=tuple(refits), photo_size=first, dist=dist, feature=feature,
        min_model_points=s.min_model_points, camera_model=camera_model,
        lens_passes=lens_passes)
