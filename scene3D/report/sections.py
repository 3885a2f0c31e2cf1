"""What the report pages share: the 3D view's section, the figures, the timings, the
focal length found from the photos, the JSON block's values and the footer."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from .. import __version__
from ..viz.drawing import robust_extent
from .page import Page
from .viewer import PreparedView
from .wording import figure_caption, quantity_rows, stage_name

__all__ = ["figures_section", "footer", "frusta_depth", "jsonable", "self_calibration_section",
           "timings_section", "view_section"]

_SELF_CALIBRATION = ("start", "camera", "start_focal_px", "photos_focal_px", "determined")


def frusta_depth(points3d: np.ndarray, centres: np.ndarray) -> float:
    """Frustum depth for display: 8 % of the cloud's robust extent (or of the cameras').

    Parameters
    ----------
    points3d : (N, 3) ndarray
        The cloud (may be empty).
    centres : (V, 3) ndarray
        The camera centres, used when the cloud is empty.

    Returns
    -------
    float
    """
    lo, hi = robust_extent(points3d if len(points3d) else centres)
    return 0.08 * max(float(np.linalg.norm(hi - lo)), 1e-9)


def view_section(page: Page, view: PreparedView, frame_note: str) -> None:
    """The "3D view" section: how to drive it, the point count, the view, its frame.

    Parameters
    ----------
    page : Page
    view : PreparedView
    frame_note : str
        What frame and scale the view shows.
    """
    page.heading("3D view")
    notes = [f"Drag to turn, scroll to zoom, click a legend entry to hide it. "
             f"{view.num_points:,} points (plotly.js {view.version})."] + view.notes
    page.view3d(view.plotly_js, view.figure_json, notes)
    page.paragraph(frame_note, "note")


def timings_section(page: Page, timings: Mapping[str, float] | None) -> None:
    """The "Timings" table (stages in words, seconds, share of the total); none without.

    Parameters
    ----------
    page : Page
    timings : mapping of str to float or None
        A summary's ``timings_s``.
    """
    if not timings:
        return
    page.heading("Timings")
    total = timings.get("total")
    rows = [(stage_name(k), f"{float(v):.2f} s") + ((f"{v / total:.0%}",) if total else ())
            for k, v in timings.items() if v is not None]
    page.table(rows, header=("stage", "time") + (("share of the whole run",) if total else ()),
               table_id="timings")
    page.paragraph("Measured by the command (the report itself and the writing of the "
                   "files come after; reconstruction.json has them).", "note")


def figures_section(page: Page, figures: Mapping[str, bytes]) -> None:
    """The "Figures" section, each captioned in words with its file name.

    Parameters
    ----------
    page : Page
    figures : mapping of str to bytes
        File name to PNG or JPEG bytes, in display order.
    """
    if not figures:
        return
    page.heading("Figures")
    for name, png in figures.items():
        page.figure(png, figure_caption(name))


def jsonable(value: Any) -> Any:
    """``value`` with numpy arrays and scalars as lists and Python numbers (for the JSON
    block).

    Parameters
    ----------
    value : Any

    Returns
    -------
    Any
    """
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    return value


def footer(extra: str = "") -> str:
    """The page's footer line: the version, and that the file loads nothing.

    Parameters
    ----------
    extra : str, default ""
        Appended.

    Returns
    -------
    str
    """
    return (f"scene3D {__version__}. A self-contained file: it loads nothing from the "
            f"network. {extra}").strip()


def self_calibration_section(page: Page, fields: Any) -> None:
    """The focal length found from the photos, when there was no calibration file.

    Parameters
    ----------
    page : Page
    fields : Any
        A summary's ``self_calibration`` (None or empty: no section).
    """
    if not isinstance(fields, Mapping) or not fields:
        return
    page.heading("Focal length from the photos")
    page.quantities(quantity_rows(fields, _SELF_CALIBRATION), "self-calibration")


