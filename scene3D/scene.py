"""``SceneReconstruction3D``: the book's class, kept as a thin stateful facade.

Usage as in *OpenCV with Python Blueprints*, chapter 4::

    scene = SceneReconstruction3D(K, dist)     # K for the native image size
    scene.load_image_pair("0004.jpg", "0005.jpg")
    fig = scene.plot_point_cloud()             # a matplotlib Figure
    result = scene.reconstruct()               # a TwoViewReconstruction

Every method delegates to the pure functions of the package; this class only
remembers the loaded images and the results, so that features and the
reconstruction are computed once per feature mode and reused by every plot.
"""

from __future__ import annotations

import logging
import os
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from .errors import log_result_warnings
from .features.matching import Matches, find_matches, normalize_feature_mode
from .geometry.camera import (
    check_intrinsics_for_native_size,
    scale_intrinsics,
    scale_intrinsics_halved,
    validate_distortion,
    validate_intrinsics,
)
from .geometry.conventions import distinct_correspondences
from .geometry.rectification import RectifiedPair, rectify_pair
from .io.images import (
    BOOK_MAX_WIDTH_PX,
    ImageSource,
    bgr_order,
    load_working_images,
    source_label,
)
from .optim.uncertainty import depth_sigmas
from .twoview import (
    TwoViewReconstruction,
    TwoViewSettings,
    reconstruct_two_view,
    require_enough_matches,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from .dense import DenseReconstruction
    from .selfcalibration import SelfCalibration, SelfCalibrationSettings

logger = logging.getLogger(__name__)


class SceneReconstruction3D:
    """Two-view 3D scene reconstruction, with the book's method names.

    Parameters
    ----------
    K : (3, 3) array_like
        Intrinsic matrix for the **native** resolution of the images you load.
    dist : array_like, optional
        OpenCV distortion coefficients (0, 4, 5, 8, 12 or 14 values).
    settings : TwoViewSettings, optional
        Thresholds of the two-view pipeline.

    Attributes (after :meth:`reconstruct` or a plot, as in the book)
    ----------------------------------------------------------------
    K, K_inv : (3, 3)
        Intrinsics of the working (downscaled, undistorted) images.
    d : (n,)
        Distortion coefficients as given (the working images are undistorted).
    img1, img2 : (H, W, 3) uint8
        The working images, BGR.
    F, E : (3, 3)
        Fundamental and essential matrices.
    Rt1, Rt2 : (3, 4)
        ``[I | 0]`` and ``[R | t]``, ``x_cam2 = R x_cam1 + t``.
    match_pts1, match_pts2 : (N, 2)
        All putative matches, each correspondence once
        (:func:`scene3D.geometry.distinct_correspondences`; ``N`` is the result's
        ``num_matches``).
    match_inliers1, match_inliers2 : (M, 2)
        The essential-matrix inliers.
    self_calibration : SelfCalibration or None
        What :meth:`self_calibrate` found (photos without a calibration file).
    """

    def __init__(self, K: ArrayLike, dist: ArrayLike | None = None,
                 settings: TwoViewSettings | None = None) -> None:
        self.K_native = validate_intrinsics(K)
        self.d = validate_distortion(dist)
        self.settings = settings or TwoViewSettings()
        self.K = self.K_native.copy()
        self.K_inv = np.linalg.inv(self.K)
        self.img1: np.ndarray | None = None
        self.img2: np.ndarray | None = None
        self.native_size: tuple[int, int] | None = None  # (width, height) as loaded
        self.image_names: tuple[str, ...] = ()  # file names, or img1, img2 for arrays
        self.halvings = 0  # times the loaded images were halved
        self._matches: dict[str, Matches] = {}
        self._results: dict[str, TwoViewReconstruction] = {}
        self._dense: dict[tuple[str, int], DenseReconstruction] = {}
        self.self_calibration: SelfCalibration | None = None

    # -- loading -----------------------------------------------------------------
    def load_image_pair(self, img1: ImageSource, img2: ImageSource, use_pyr_down: bool = True,
                        max_width: int = BOOK_MAX_WIDTH_PX, *, rgb: bool = False) -> None:
        """Load two images (paths or arrays), undistort them and downscale them like the book.

        While wider than ``max_width`` (the book's 1200 px) the images are halved
        and ``K`` is scaled to match (3072 px -> 768 px). The book halves with
        ``cv2.pyrDown``; we average 2x2 blocks, which a JPEG decoder does for free
        (see :mod:`scene3D.io.images`). ``use_pyr_down=False`` keeps the native size.

        Parameters
        ----------
        img1, img2 : str, os.PathLike or ndarray
            Image files, or arrays ``(H, W, 3)`` BGR / ``(H, W)`` grey ``uint8``, at the
            native size ``K`` is for.
        use_pyr_down : bool, default True
            Halve while wider than ``max_width``; False keeps the native size.
        max_width : int, default BOOK_MAX_WIDTH_PX
            Largest working width (px).
        rgb : bool, default False
            The arrays are RGB (PIL, imageio), not BGR as cv2 loads them
            (:func:`scene3D.io.images.bgr_order`); files are read as they are.


        Raises
        ------
        FileNotFoundError
            A path does not exist.
        ValueError
            A file is not an image, the two images differ in size or are one photo (a
            copy under another name: the same pixels), or ``K`` cannot be a
            camera matrix for their native size (a principal point far outside them, a
            focal length no lens has: :func:`~scene3D.geometry.camera.check_intrinsics_for_size`),
            as when ``K`` was calibrated on larger photos than these.
        """
        img1, img2 = bgr_order(img1, rgb), bgr_order(img2, rgb)
        (a, b), size, levels = load_working_images(
            (img1, img2), self.K_native, self.d, max_width if use_pyr_down else None,
            ("img1", "img2"))
        check_intrinsics_for_native_size(self.K_native, size)
        if np.array_equal(a, b):
            first, second = source_label(img1, "img1"), source_label(img2, "img2")
            raise ValueError(f"'{first}' and '{second}' are the same photo (the same pixels): "
                             "a pair needs two views of the scene")
        self.img1, self.img2 = a, b
        self.image_names = tuple(Path(source_label(src, name)).name
                                 for src, name in ((img1, "img1"), (img2, "img2")))
        self.native_size = size
        self.halvings = levels
        self.K = scale_intrinsics_halved(self.K_native, levels)
        self.K_inv = np.linalg.inv(self.K)
        self._matches.clear()
        self._results.clear()
        self._dense.clear()
        self.self_calibration = None
        logger.info("working size %dx%d (halved %d times)", a.shape[1], a.shape[0], levels)

    def _require_images(self) -> tuple[np.ndarray, np.ndarray]:
        if self.img1 is None or self.img2 is None:
            raise RuntimeError("call load_image_pair() first")
        return self.img1, self.img2

    # -- computation (cached per feature mode) -----------------------------------
    def matches(self, feat_mode: str = "SIFT") -> Matches:
        """Matched points for ``feat_mode``, computed once and reused.

        Parameters
        ----------
        feat_mode : str, default "SIFT"
            Feature mode (:data:`scene3D.features.FEATURE_MODES`).

        Returns
        -------
        Matches
            ``pts1, pts2`` ``(N, 2)`` pixels of the working images (OpenCV convention).
        """
        mode = normalize_feature_mode(feat_mode)
        if mode not in self._matches:
            img1, img2 = self._require_images()
            self._matches[mode] = find_matches(img1, img2, mode)
        return self._matches[mode]

    def reconstruct(self, feat_mode: str = "SIFT") -> TwoViewReconstruction:
        """Estimate the pose and triangulate the points (cached per feature mode).

        Also sets the book's attributes ``F``, ``E``, ``Rt1``, ``Rt2``,
        ``match_pts1/2`` and ``match_inliers1/2``.

        Parameters
        ----------
        feat_mode : str, default "SIFT"
            Feature mode (:data:`scene3D.features.FEATURE_MODES`).

        Returns
        -------
        TwoViewReconstruction
            ``x_cam2 = R x_cam1 + t`` with ``|t| = 1`` (the scale is unknown); points in the
            camera-1 frame.


        Raises
        ------
        ReconstructionError
            A degenerate pair (too few matches, no parallax, no cheirality winner).
        """
        mode = normalize_feature_mode(feat_mode)
        matches = self.matches(mode)
        if mode not in self._results:
            img1, img2 = self._require_images()
            self._results[mode] = reconstruct_two_view(img1, matches, self.K, self.settings,
                                                       img2)
        result = self._results[mode]
        distinct = distinct_correspondences(matches.pts1, matches.pts2)
        self.match_pts1, self.match_pts2 = matches.pts1[distinct], matches.pts2[distinct]
        self.match_inliers1, self.match_inliers2 = result.inlier_pts1, result.inlier_pts2
        self.F, self.E = result.F, result.E
        self.Rt1, self.Rt2 = result.Rt1, result.Rt2
        return result

    def save(self, folder: str | os.PathLike, feat_mode: str = "SIFT") -> list[Path]:
        """Write the pair's reconstruction (:meth:`reconstruct`, computed if needed) into
        ``folder``: ``point_cloud.ply``, ``cameras.json`` and ``colmap/`` at the size of
        the loaded photos, with their distortion
        (:meth:`scene3D.twoview.TwoViewReconstruction.save`). The views are named by
        their file names (``img1``, ``img2`` for arrays), prefixed ``1_`` and ``2_`` when
        they share one. Returns the paths written.

        Parameters
        ----------
        folder : str or os.PathLike
            Target folder (created if needed).
        feat_mode : str, default "SIFT"
            Feature mode (:data:`scene3D.features.FEATURE_MODES`).

        Returns
        -------
        list of Path


        Raises
        ------
        ReconstructionError
            As :meth:`reconstruct`.
        """
        from .io.export import colmap_image_name

        result = self.reconstruct(feat_mode)
        img1, _ = self._require_images()
        names = self.image_names
        if colmap_image_name(names[0]) == colmap_image_name(names[1]):  # a/IMG.jpg, b/IMG.jpg
            names = tuple(f"{i}_{name}" for i, name in enumerate(names, start=1))
        return result.save(folder, (img1.shape[1], img1.shape[0]), names, self.native_size,
                           self.d)

    def self_calibrate(self, feat_mode: str = "SIFT", prior_sigma_log: float = 0.5,
                       prior_source: str = "prior",
                       search: SelfCalibrationSettings | None = None) -> SelfCalibration:
        """Find the focal length from the loaded pair, starting from the one in ``K``.

        For photos without a calibration: ``K`` (given to the constructor) holds the
        EXIF or prior focal length and the principal point at the image centre
        (:class:`scene3D.geometry.intrinsics_prior.FocalPrior`), ``prior_sigma_log`` its
        uncertainty and ``prior_source`` (``"exif"`` or ``"prior"``) where it comes
        from. :func:`scene3D.selfcalibration.self_calibrate_pair` refines it on the
        matches of ``feat_mode``; ``K`` (and ``K_native``) become the result's, and
        :meth:`reconstruct` and every plot use them. The doubts about the focal length
        join the reconstruction's ``warnings`` (and can make it untrusted).

        Parameters
        ----------
        feat_mode : str, default "SIFT"
            Feature mode (:data:`scene3D.features.FEATURE_MODES`).
        prior_sigma_log : float, default 0.5
            Standard deviation of the prior's ``log f``.
        prior_source : str, default "prior"
            Where ``K``'s focal length comes from: ``"exif"`` or ``"prior"``.
        search : SelfCalibrationSettings or None, default None
            The search's settings; None for the defaults.

        Returns
        -------
        SelfCalibration


        Raises
        ------
        ReconstructionError
            The pair is refused under every focal length tried.
        """
        from .selfcalibration import self_calibrate_pair

        mode = normalize_feature_mode(feat_mode)
        matches = self.matches(mode)
        require_enough_matches(matches, self.settings)
        calibration = self_calibrate_pair(matches.pts1, matches.pts2, self.K, prior_sigma_log,
                                          prior_source, self.settings, search)
        up = 2.0 ** self.halvings
        self.K = calibration.K.copy()
        self.K_inv = np.linalg.inv(self.K)
        self.K_native = scale_intrinsics(self.K, up, up)
        self._results.clear()
        self._dense.clear()
        self.self_calibration = calibration
        img1, img2 = self._require_images()
        result = reconstruct_two_view(img1, matches, self.K, self.settings, img2)
        # The pose's uncertainty includes the focal length's (the calibration's geometry).
        marginal = calibration.geometry
        uncertainty = replace(result.uncertainty, pose_covariance=marginal.pose_covariance,
                              rotation_sigma_deg=marginal.rotation_sigma_deg,
                              translation_sigma_deg=marginal.translation_sigma_deg,
                              depth_sigmas=depth_sigmas(
                                  result.points3d, result.K, result.R, result.t,
                                  marginal.pose_covariance, result.noise_sigma_px))
        self._results[mode] = replace(result, trusted=result.trusted and calibration.focal_trusted,
                                      warnings=result.warnings + calibration.warnings,
                                      uncertainty=uncertainty)
        log_result_warnings(logger, calibration.warnings)
        self.reconstruct(mode)
        return calibration

    def rectify(self, feat_mode: str = "SIFT") -> RectifiedPair:
        """Rectify the working pair with the estimated pose.

        Parameters
        ----------
        feat_mode : str, default "SIFT"
            Feature mode (:data:`scene3D.features.FEATURE_MODES`).

        Returns
        -------
        RectifiedPair

        Raises
        ------
        ReconstructionError
            As :meth:`reconstruct`.
        """
        result = self.reconstruct(feat_mode)
        img1, img2 = self._require_images()
        return rectify_pair(img1, img2, self.K, result.R, result.t)

    def dense_point_cloud(self, feat_mode: str = "SIFT", block_size: int = 5
                          ) -> DenseReconstruction:
        """Dense, coloured point cloud by semi-global matching on the rectified pair.

        Uses the pose and the sparse matches of :meth:`reconstruct` (the disparity
        range comes from them); points are in the camera-1 frame, same scale as
        the sparse cloud. Cached per feature mode and block size.

        Parameters
        ----------
        feat_mode : str, default "SIFT"
            Feature mode (:data:`scene3D.features.FEATURE_MODES`).
        block_size : int, default 5
            SGBM block size (px, odd).

        Returns
        -------
        DenseReconstruction

        Raises
        ------
        ReconstructionError
            As :meth:`reconstruct`, or when dense matching cannot serve the pair.
        """
        from .dense import dense_point_cloud

        key = (normalize_feature_mode(feat_mode), block_size)
        if key not in self._dense:
            result = self.reconstruct(feat_mode)
            img1, img2 = self._require_images()
            self._dense[key] = dense_point_cloud(img1, img2, self.K, result.R, result.t,
                                                 result.pts1, result.pts2, block_size)
        return self._dense[key]

    # -- the book's plots ----------------------------------------------------------
    def plot_optic_flow(self) -> Figure:
        """Figure of the optic flow (``"flow"`` mode tracks) over image 1."""
        from .viz.plotting import plot_optic_flow

        m = self.matches("flow")
        return plot_optic_flow(self._require_images()[0], m.pts1, m.pts2)

    def draw_epipolar_lines(self, feat_mode: str = "SIFT", num_lines: int = 20) -> Figure:
        """Figure of both images with epipolar lines of inlier matches.

        Parameters
        ----------
        feat_mode : str, default "SIFT"
            Feature mode (:data:`scene3D.features.FEATURE_MODES`).
        num_lines : int, default 20
            Number of inlier matches drawn.

        Returns
        -------
        Figure
        """
        from .viz.plotting import plot_epipolar_lines

        result = self.reconstruct(feat_mode)
        img1, img2 = self._require_images()
        return plot_epipolar_lines(img1, img2, result.F, result.inlier_pts1,
                                   result.inlier_pts2, num_lines)

    def plot_rectified_images(self, feat_mode: str = "SIFT") -> Figure:
        """Figure of the rectified pair side by side.

        Parameters
        ----------
        feat_mode : str, default "SIFT"
            Feature mode (:data:`scene3D.features.FEATURE_MODES`).

        Returns
        -------
        Figure
        """
        from .viz.plotting import plot_rectified

        return plot_rectified(self.rectify(feat_mode))

    def plot_point_cloud(self, feat_mode: str = "SIFT") -> Figure:
        """Figure of the triangulated, coloured point cloud.

        Parameters
        ----------
        feat_mode : str, default "SIFT"
            Feature mode (:data:`scene3D.features.FEATURE_MODES`).

        Returns
        -------
        Figure
        """
        from .viz.plotting import plot_point_cloud

        result = self.reconstruct(feat_mode)
        return plot_point_cloud(result.points3d, result.colors)

