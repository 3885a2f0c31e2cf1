"""What the reports call the numbers of a summary: a label, a unit and one line of
explanation for each field a page shows, and the number formatted as the command's
summary lines format it.

The summaries (``reconstruction.json``) keep their field names for programs; a page shows
only the fields named here, in words, and every field in full in its collapsed JSON block.
A field not named here is left out of the tables rather than shown under its name.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["CAMERA_MODELS", "FIELDS", "STAGES", "Quantity", "display_path", "matrix_rows",
           "quantity_rows", "stage_name", "figure_caption", "CALIBRATION_NOTES"]


@dataclass(frozen=True)
class Quantity:
    """How a page shows one summary field.

    Attributes
    ----------
    label : str
        Its name in words.
    unit : str
        Appended to the number ("px", "deg", "%"); "" for none.
    digits : str
        A format spec for floats (``".3f"``, ``".2g"``); ints and text are shown as they are.
    explain : str
        One line a reader unfamiliar with the method understands.
    percent : bool
        The value is a share (0 to 1), shown times 100 with the unit "%".
    words : mapping of str to str or None
        Text values in words (``"pinhole"`` -> ``"pinhole (no lens distortion)"``).
    """

    label: str
    unit: str = ""
    digits: str = ".4g"
    explain: str = ""
    percent: bool = False
    words: Mapping[str, str] | None = None

    def text(self, value: Any) -> str:
        """``value`` as the page shows it, with the unit ("0.175 px", "0.029 %", "yes").

        Parameters
        ----------
        value : Any
            A number, a bool, a string, a short list of numbers, or None.

        Returns
        -------
        str
            "-" for None or a number that is not finite.
        """
        if value is None:
            return "-"
        if isinstance(value, (bool, np.bool_)):
            return "yes" if value else "no"
        if isinstance(value, (list, tuple, np.ndarray)):
            return " x ".join(self._number(v) for v in value) + self._unit()
        if isinstance(value, str) and self.words is not None:
            return self.words.get(value, value)
        if isinstance(value, (int, float, np.integer, np.floating)):
            if not math.isfinite(float(value)):
                return "-"
            return self._number(value) + self._unit()
        return str(value)

    def _number(self, value: Any) -> str:
        if isinstance(value, (int, np.integer)) and not self.percent:
            return str(int(value))
        value = float(value) * (100.0 if self.percent else 1.0)
        return f"{value:{self.digits}}"

    def _unit(self) -> str:
        unit = "%" if self.percent else self.unit
        return f" {unit}" if unit else ""


_Q = Quantity
#: The camera models in words (COLMAP's names in brackets, as the files spell them).
CAMERA_MODELS = {
    "pinhole": "pinhole: no lens distortion (PINHOLE)",
    "simple_pinhole": "pinhole with one focal length: no lens distortion (SIMPLE_PINHOLE)",
    "simple_radial": "one radial distortion coefficient (SIMPLE_RADIAL)",
    "radial": "two radial distortion coefficients (RADIAL)",
    "opencv": "OpenCV's distortion: k1, k2, p1, p2 (OPENCV)",
    "full_opencv": "OpenCV's full distortion (FULL_OPENCV)",
}
#: The summary fields the pages show, by their name in ``reconstruction.json``.
FIELDS: dict[str, Quantity] = {
    # two views
    "num_matches": _Q("matches", explain="keypoint pairs whose descriptors match between the "
                      "two photos, before the geometry is known"),
    "num_inliers": _Q("matches that fit the geometry", explain="matches consistent with one "
                      "relative pose (the essential matrix), within the noise"),
    "num_points": _Q("3D points", explain="inliers triangulated in front of both cameras"),
    "reprojection_rmse_px": _Q("reprojection error (RMS)", "px", ".3f",
                               "how far, per coordinate, the 3D points land from where "
                               "they were measured in the photos"),
    "median_parallax_deg": _Q("median parallax", "deg", ".2f", "the median angle between "
                              "the two rays of a point: below about 2 deg depth is poorly "
                              "determined"),
    "homography_inlier_ratio": _Q("matches a plane explains", explain="how many of the "
                                  "inliers one homography also fits: near 100 % means a flat "
                                  "scene or too little baseline", digits=".1f", percent=True),
    "robust_starts": _Q("robust estimations run", explain="independent RANSAC runs of the "
                        "essential matrix; more than one when the first did not settle"),
    "robust_spread_deg": _Q("spread of the robust estimations", "deg", ".2g", "how far the "
                            "other runs' poses lie from the chosen one (0: all agree)"),
    "focal_scale": _Q("focal length the matches call for", "x the calibration's", ".3f",
                      "1.000 when the calibration's focal length fits these photos"),
    "focal_scale_sigma": _Q("its uncertainty (1 sigma)", "x the calibration's", ".2g",
                            "infinite when the pair cannot tell"),
    "focal_ratio": _Q("focal length of photo 2 over photo 1", explain="what the matches call "
                      "for: 1.000 when one calibration fits both photos", digits=".4f"),
    "focal_ratio_sigma": _Q("its uncertainty (1 sigma)", digits=".2g"),
    "rotation_sigma_deg": _Q("rotation uncertainty (1 sigma)", "deg", ".3f", "from the "
                             "keypoint noise, propagated to camera 2's rotation"),
    "translation_sigma_deg": _Q("direction-of-travel uncertainty (1 sigma)", "deg", ".3f",
                                "the same for the direction from camera 1 to camera 2"),
    "noise_sigma_px": _Q("keypoint noise (1 sigma)", "px", ".3f", "the spread of the "
                         "inliers about the geometry, per coordinate"),
    "noise_cut_share": _Q("matches cut off as noise", explain="matches that fit the pose "
                          "but lie beyond the inlier threshold (the uncertainty allows "
                          "for them)", digits=".1f", percent=True),
    "behind_share": _Q("points behind a camera", explain="inliers whose point lies behind a "
                       "camera by more than the noise explains: wrong matches near their "
                       "epipolar lines", digits=".1f", percent=True),
    "flow_gain": _Q("dense optical flow check", explain="how much more of the dense flow "
                    "between the photos another pose would explain (near 0: the flow "
                    "agrees with this pose)", digits=".1f", percent=True),
    "distortion_k": _Q("lens distortion the matches call for", explain="the radial "
                       "coefficient of the division model: 0 none, negative barrel",
                       digits=".4f"),
    "distortion_pose_shift_deg": _Q("pose change with that distortion", "deg", ".3f",
                                    "how far the pose moves when the distortion is allowed "
                                    "for"),
    "focal_px_sigma": _Q("focal length uncertainty (1 sigma)", "px", ".1f",
                         "of the focal length found from the photos"),
    "calibration_source": _Q("intrinsics from", explain="where the focal length and "
                             "principal point come from",
                             words={"file": "the calibration file"}),
    "feature": _Q("keypoints", explain="the detector and descriptor that ran"),
    "image_size": _Q("working image size", "px", explain="the size the photos were "
                     "reconstructed at (pixels below are of this size)"),
    "native_image_size": _Q("photo size", "px", explain="as stored"),
    "trusted": _Q("trusted", explain="no check raised a doubt"),
    # many views
    "views": _Q("views", explain="photos given"),
    "registered": _Q("views registered", explain="photos whose camera was placed in the "
                     "largest model"),
    "points": _Q("3D points", explain="points triangulated and kept after bundle adjustment"),
    "mean_track_length": _Q("mean track length", digits=".2f", explain="how many photos "
                            "see a 3D point, on average (2 is the least)"),
    "pair_selection": _Q("pairs compared", explain="how the pairs of photos to match were "
                         "chosen"),
    "matched_pairs": _Q("pairs matched", explain="pairs of photos whose keypoints were "
                        "matched"),
    "verified_pairs": _Q("pairs verified", explain="pairs with enough matches that fit one "
                         "relative pose"),
    "camera_model": _Q("camera model", explain="how the lens maps rays to pixels",
                       words=CAMERA_MODELS),
    "status": _Q("status", explain="'ok' when the model passed its consistency check"),
    # ground truth
    "median_center_error_fraction": _Q("camera centre error, median", explain="distance to "
                                       "the true centre after the best similarity, as a "
                                       "share of the scene's extent", digits=".3f",
                                       percent=True),
    "max_center_error_fraction": _Q("camera centre error, worst", digits=".3f", percent=True,
                                    explain="the largest of those distances"),
    "median_rotation_error_deg": _Q("rotation error, median", "deg", ".3f",
                                    "angle between each camera's rotation and the true one"),
    "max_rotation_error_deg": _Q("rotation error, worst", "deg", ".3f",
                                 "the largest of those angles"),
    "true_focal_px": _Q("true focal length", "px", ".1f", "from the ground-truth cameras, "
                        "at the working size"),
    "focal_error_fraction": _Q("focal length error", digits="+.2f", percent=True,
                               explain="the focal length found over the true one, minus 1"),
    # a focal length found from the photos (the summaries' self_calibration)
    "start": _Q("where the focal length started", explain="the EXIF focal length, or a "
                "guess from the image size without one"),
    "camera": _Q("camera (EXIF)", explain="as the photos' EXIF names it"),
    "start_focal_px": _Q("starting focal length", "px", ".1f"),
    "photos_focal_px": _Q("focal length the photos call for", "px", ".1f",
                          "from the matches alone, before the prior is combined"),
    "determined": _Q("the photos determine it", explain="no: the start value was kept"),
    # the dense cloud
    "disparity_range_px": _Q("disparities searched", "px", explain="from the smallest to "
                             "the largest shift between the rectified photos"),
}

#: Timing stages in words (a stage not named here is shown with its underscores as spaces).
STAGES: dict[str, str] = {"flow check": "dense optical flow check",
                          "bundle_adjustment": "bundle adjustment",
                          "initialisation": "initial pair", "write": "writing files"}


#: Captions of the figures the commands embed, by file name.
FIGURES: dict[str, str] = {
    "optic_flow.png": "Optic flow: each match as a line from image 1 to image 2",
    "epipolar_lines.png": "Epipolar lines: a point in one photo lies on its line in the "
                          "other when the geometry is right",
    "rectified.png": "The rectified pair: matching points on the same row",
    "point_cloud.png": "The sparse cloud from above and to the left of camera 1",
    "disparity.png": "Disparity of the dense matching (brighter: nearer)",
    "cameras.png": "Cameras and points from above",
}


#: One line on each row of a calibration's table, by its label (before any " (unit)").
CALIBRATION_NOTES: dict[str, str] = {
    "image size": "of the calibration images, in px",
    "board": "the pattern and its square size",
    "views kept": "images whose board was found and kept",
    "views dropped": "images dropped as outliers (their error is far above the others')",
    "RMS reprojection error": "how far, per coordinate, the board's corners land from where "
                              "they were detected",
    "corner noise, 1 sigma per coordinate": "the detection noise the residuals show",
    "fx": "focal length along x, in pixels", "fy": "focal length along y, in pixels",
    "cx": "principal point, x", "cy": "principal point, y",
    "k1": "radial distortion (OpenCV), with its 1 sigma",
    "k2": "radial distortion, second order", "k3": "radial distortion, third order",
    "p1": "tangential distortion", "p2": "tangential distortion",
    "k4": "rational model, denominator", "k5": "rational model, denominator",
    "k6": "rational model, denominator",
}


def figure_caption(name: str) -> str:
    """A figure's caption in words with its file name ("Optic flow: ... (optic_flow.png)").

    Parameters
    ----------
    name : str
        The figure's file name (a calibration's ``NAME_coverage.png`` among them).

    Returns
    -------
    str
    """
    for suffix, words in (("_coverage.png", "Where the board's corners fell in the images"),
                          ("_view_errors.png", "Reprojection error of each view"),
                          ("_uncertainty.png", "Projection uncertainty over the image")):
        if name.endswith(suffix):
            return f"{words} ({name})"
    return f"{FIGURES[name]} ({name})" if name in FIGURES else name


def stage_name(stage: str) -> str:
    """A timing stage in words ("bundle adjustment").

    Parameters
    ----------
    stage : str
        A key of a summary's ``timings_s``.

    Returns
    -------
    str
    """
    return STAGES.get(stage, stage.replace("_", " "))


def quantity_rows(values: Mapping[str, Any], keys: Iterable[str] | None = None
                  ) -> list[tuple[str, str, str]]:
    """``(label, value with unit, explanation)`` of each field of ``values`` that
    :data:`FIELDS` names, in the order of ``keys`` (default: of ``values``).

    Fields absent from ``values``, None, or holding a mapping or a list other than 1 to 4
    numbers are left out.

    Parameters
    ----------
    values : mapping
        A summary, or a part of one.
    keys : iterable of str or None, default None
        Which fields, in order.

    Returns
    -------
    list of (str, str, str)
    """
    rows = []
    for key in (values if keys is None else keys):
        if key not in FIELDS or key not in values:
            continue
        value = values[key]
        if value is None or isinstance(value, Mapping) or (
                isinstance(value, (list, tuple, np.ndarray)) and not _short_numbers(value)):
            continue
        q = FIELDS[key]
        rows.append((q.label, q.text(value), q.explain))
    return rows


def _short_numbers(values: Any) -> bool:
    """1 to 4 numbers (a size, a range): shown in one cell; longer lists are not."""
    return 0 < len(values) <= 4 and all(
        isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
        for v in values)


def matrix_rows(matrix: Any, digits: str = ".4f") -> list[list[str]]:
    """The rows of a small matrix or vector as text, for a table (``R``, ``t``, ``K``).

    Parameters
    ----------
    matrix : (M, N) or (N,) array_like
        The numbers.
    digits : str, default ".4f"
        Format spec.

    Returns
    -------
    list of list of str
    """
    m = np.atleast_2d(np.asarray(matrix, dtype=np.float64))
    return [[f"{v:{digits}}" for v in row] for row in m]


def display_path(path: str | os.PathLike, base: str | os.PathLike | None = None) -> str:
    """``path`` relative to ``base`` (default: the working folder) when it lies inside it,
    else as given: the names a report shows are those its reader typed.

    Parameters
    ----------
    path : str or path-like
        A file or folder.
    base : str or path-like or None, default None
        Where the command ran; None for the working folder.

    Returns
    -------
    str
    """
    p = Path(path)
    try:
        return p.resolve().relative_to(Path(base or os.getcwd()).resolve()).as_posix()
    except (ValueError, OSError):
        return str(path)
