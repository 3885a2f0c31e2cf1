"""A camera's calibration from its views, with what to trust it for.

:func:`calibrate_views` runs the chain that ``scene3d calibrate`` runs on the views
:func:`scene3D.calibration.views.collect_views` found: the solve
(:func:`scene3D.calibration.solve.calibrate`, outlier views dropped), the coverage of the
image by the corners kept, the projection-uncertainty map
(:func:`scene3D.calibration.uncertainty.uncertainty_map`) and the warnings both give. The
:class:`BoardCalibration` it returns says what the command prints
(:meth:`~BoardCalibration.summary_lines`), the values of its report's table
(:meth:`~BoardCalibration.report_numbers`) and what the calibration file holds beside
``K`` and the distortion (:meth:`~BoardCalibration.file_metadata`).

Pixels as in :mod:`scene3D.geometry`; sizes ``(width, height)``.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

import numpy as np

from ..errors import CalibrationError
from .board import BoardSpec, Detection
from .solve import MAX_RMS_PX, CalibrationResult, calibrate, corner_coverage, coverage_warnings
from .uncertainty import CORNER_LIMIT_PX, UncertaintyMap, format_px, uncertainty_map

#: The names of the distortion coefficients, in OpenCV's order.
_DISTORTION = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")


@dataclass(frozen=True)
class BoardCalibration:
    """A calibration with its coverage and its projection uncertainty (:func:`calibrate_views`).

    Attributes
    ----------
    result : CalibrationResult
        ``K``, the distortion, the errors and the covariance of the intrinsics.
    views : list of Detection
        The views the solve kept (outliers dropped).
    coverage : (rows, cols) int
        Corners of ``views`` per cell of the image
        (:func:`scene3D.calibration.solve.corner_coverage`).
    uncertainty : UncertaintyMap
        The projection uncertainty over the image.
    warnings : tuple of str
        Parts of the image the corners left empty, then where the projection is uncertain.
    """

    result: CalibrationResult
    views: list[Detection]
    coverage: np.ndarray
    uncertainty: UncertaintyMap
    warnings: tuple[str, ...]

    def summary_lines(self) -> list[str]:
        """What ``scene3d calibrate`` prints: the error, ``K`` and the distortion with their
        standard deviations, each view's error, the views dropped and the uncertainty.

        Returns
        -------
        list of str
        """
        result, umap = self.result, self.uncertainty
        K, d, std = result.K, result.dist, result.std_intrinsics
        lines = [
            f"RMS reprojection error: {result.rms_px:.4f} px over "
            f"{len(result.per_view_errors_px)} views ({result.image_size[0]}x"
            f"{result.image_size[1]}, {result.board.describe()})",
            f"fx = {K[0, 0]:.3f} +- {std['fx']:.3f}   fy = {K[1, 1]:.3f} +- {std['fy']:.3f}",
            f"cx = {K[0, 2]:.3f} +- {std['cx']:.3f}   cy = {K[1, 2]:.3f} +- {std['cy']:.3f}",
            "distortion: " + ", ".join(
                f"{n} = {v:+.5f} +- {std.get(n, float('nan')):.5f}"
                for n, v in zip(("k1", "k2", "p1", "p2", "k3"), d)),
            "per-view RMS (px): " + ", ".join(
                f"{n} {e:.3f}" for n, e in result.per_view_errors_px.items()),
        ]
        if result.rejected_views:
            lines.append("dropped as outliers (> 3x median error): " + ", ".join(
                f"{n} ({e:.2f} px)" for n, e in result.rejected_views.items()))
        corners = ", ".join(format_px(v) for v in umap.corners_px.values())
        lines.append(f"projection uncertainty (1 sigma): median {format_px(umap.median_px)}, "
                     f"worst {format_px(umap.worst_px)}, centre {format_px(umap.centre_px)}, "
                     f"corners {corners}"
                     + (f"; no ray reaches {umap.unreachable_share:.1%} of the image"
                        if umap.unreachable_share else ""))
        return lines

    def report_numbers(self) -> dict:
        """The named values of the calibration report's table.

        Returns
        -------
        dict
            Label -> number or text (``"fx (px)": "533.457 +- 0.612"``).
        """
        result = self.result
        std = result.std_intrinsics
        numbers: dict = {"image size": f"{result.image_size[0]}x{result.image_size[1]}",
                         "board": result.board.describe(),
                         "views kept": len(result.per_view_errors_px),
                         "views dropped": len(result.rejected_views),
                         "RMS reprojection error (px)": result.rms_px}
        if result.covariance is not None:
            numbers["corner noise, 1 sigma per coordinate (px)"] = \
                result.covariance.residual_sigma_px
        for name, (i, j) in {"fx": (0, 0), "fy": (1, 1), "cx": (0, 2), "cy": (1, 2)}.items():
            numbers[f"{name} (px)"] = f"{result.K[i, j]:.3f} +- {std[name]:.3f}"
        for name, value in zip(_DISTORTION, result.dist):
            numbers[name] = f"{value:+.5f} +- {std.get(name, float('nan')):.5f}"
        return numbers

    def file_metadata(self, date: dt.datetime | None = None) -> dict:
        """What the calibration file holds beside ``K``, the distortion and the image size.

        Parameters
        ----------
        date : datetime, optional
            The calibration's date (default: now, UTC), written to the second.

        Returns
        -------
        dict
            ``rms_px``, ``per_view_errors`` ``(1, V)``, ``view_names`` (joined by ';'),
            ``std_intrinsics`` ``(1, 4)`` (fx, fy, cx, cy), the projection uncertainty's
            median and worst (px), ``board``, ``square_size_m`` and ``calibration_date``
            (:func:`scene3D.io.calibration.save_calibration`'s ``extras``).
        """
        result, umap = self.result, self.uncertainty
        date = dt.datetime.now(dt.timezone.utc) if date is None else date
        return {
            "rms_px": result.rms_px,
            "per_view_errors": np.array(list(result.per_view_errors_px.values())
                                        ).reshape(1, -1),
            "view_names": ";".join(result.per_view_errors_px),
            "std_intrinsics": np.array([result.std_intrinsics[k]
                                        for k in ("fx", "fy", "cx", "cy")]).reshape(1, -1),
            "projection_uncertainty_median_px": umap.median_px,
            "projection_uncertainty_worst_px": umap.worst_px,
            "board": result.board.describe(),
            "square_size_m": result.board.square_size_m,
            "calibration_date": date.isoformat(timespec="seconds"),
        }


def calibrate_views(views: list[Detection], image_size: tuple[int, int], board: BoardSpec,
                    *, reject_outliers: bool = True, max_rms_px: float | None = MAX_RMS_PX,
                    uncertainty_limit_px: float = CORNER_LIMIT_PX) -> BoardCalibration:
    """Calibrate from the board's views, then measure the coverage and the uncertainty.

    Parameters
    ----------
    views : list of Detection
        At least 3 (:func:`scene3D.calibration.views.collect_views`).
    image_size : tuple[int, int]
        (width, height) of every view.
    board : BoardSpec
    reject_outliers : bool
        Drop views whose error exceeds three times the median, and solve again.
    max_rms_px : float or None
        Refuse a result whose RMS reprojection error exceeds this (None: no limit).
    uncertainty_limit_px : float
        Warn when the projection uncertainty (1 sigma) at an image corner or at the
        centre exceeds this.

    Returns
    -------
    BoardCalibration

    Raises
    ------
    CalibrationError
        The solve failed, its RMS error is above ``max_rms_px`` (reason
        ``"corners_do_not_fit"``, with ``rms_px``), or it gave no covariance of the
        intrinsics.
    """
    result = calibrate(views, image_size, board, reject_outliers=reject_outliers,
                       max_rms_px=max_rms_px)
    kept = [v for v in views if v.name in result.per_view_errors_px]
    counts = corner_coverage([v.image_points for v in kept], image_size)
    if result.covariance is None:
        raise CalibrationError("no covariance of the intrinsics: the projection uncertainty "
                               "cannot be computed")
    umap = uncertainty_map(result.K, result.dist, result.covariance, image_size,
                           limit_px=uncertainty_limit_px)
    return BoardCalibration(result, kept, counts, umap,
                            tuple(coverage_warnings(counts) + umap.warnings))
