"""Self-contained HTML reports of a reconstruction or a calibration.

The reports read results and draw nothing new: numbers from the summaries the commands
write as JSON, shown in words with their units (:mod:`scene3D.report.wording`), figures as
the PNG bytes the commands write, per-view numbers read from a model's observations
(:mod:`scene3D.report.diagnostics`), and for reconstructions an interactive 3D view
(plotly.js from the installed ``plotly`` package, inlined compressed; see
:mod:`scene3D.report.viewer`). Each function returns the page as an :class:`Html`
(``.text()`` is the string); the command writes it with
:func:`scene3D.io.export.atomic_write_pieces` (atomically, with the other outputs).

- :func:`two_view_report` (:mod:`~scene3D.report.two_view`): ``report.html`` of
  ``chapter4.py`` / ``scene3d reconstruct``;
- :func:`multi_view_report` (:mod:`~scene3D.report.multi_view`): ``report.html`` of
  ``scene3d reconstruct-views``;
- :func:`colmap_report` (:mod:`~scene3D.report.multi_view`): ``report.html`` of
  ``scene3d report MODEL_DIR``, for any COLMAP text model;
- :func:`reconstruction_report` (:mod:`~scene3D.report.multi_view`): the same page from
  a reconstruction in memory, with its dense run (:mod:`~scene3D.report.dense`);
- :func:`calibration_report` (:mod:`~scene3D.report.calibration`): ``NAME_report.html`` of
  ``calibrate.py``.

What the pages share is in :mod:`~scene3D.report.sections`.
"""

from __future__ import annotations

from .calibration import calibration_report
from .dense import DenseRun, dense_section, depth_thumbnail
from .diagnostics import ViewDiagnostics, view_diagnostics
from .multi_view import (
    colmap_layers,
    colmap_report,
    colmap_summary,
    multi_view_layers,
    multi_view_report,
    reconstruction_report,
)
from .page import Html
from .two_view import two_view_layers, two_view_report
from .viewer import (
    MAX_VIEW_POINTS,
    CameraLayer,
    CloudLayer,
    MissingViewerError,
    PreparedView,
    prepare_view,
)

__all__ = [
    "MAX_VIEW_POINTS", "CameraLayer", "CloudLayer", "DenseRun", "Html", "MissingViewerError",
    "PreparedView", "ViewDiagnostics", "calibration_report", "colmap_layers", "colmap_report",
    "colmap_summary", "dense_section", "depth_thumbnail", "multi_view_layers",
    "multi_view_report", "prepare_view", "reconstruction_report", "two_view_layers",
    "two_view_report", "view_diagnostics",
]
