"""Small charts drawn as inline SVG for the reports: a histogram and a view-by-view
matrix. Plain text, no plotting library, nothing loaded when the page opens."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .page import esc

__all__ = ["histogram_svg", "shared_points_svg"]

_BAR = "#4a78b5"


def histogram_svg(counts: ArrayLike, edges: ArrayLike, x_label: str, y_label: str,
                  tick_labels: Sequence[str] | None = None, width: int = 460,
                  height: int = 220) -> str:
    """A bar chart of ``counts`` over the bins ``edges``.

    Parameters
    ----------
    counts : (B,) array_like
        The count of each bin.
    edges : (B + 1,) array_like
        The bins' edges (labels at the edges unless ``tick_labels``).
    x_label, y_label : str
        Axis titles.
    tick_labels : sequence of str or None, default None
        One label under each bar instead of the edges (for whole-number bins).
    width, height : int
        Size in CSS pixels.

    Returns
    -------
    str
        An ``<svg>`` element; each bar's tooltip gives its bin and count.
    """
    counts = np.asarray(counts, dtype=np.float64)
    edges = np.asarray(edges, dtype=np.float64)
    left, right, top, bottom = 48, 10, 10, 44
    w, h = width - left - right, height - top - bottom
    peak = max(float(counts.max()) if counts.size else 0.0, 1.0)
    bar_w = w / max(len(counts), 1)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
           f'role="img" aria-label="{esc(x_label)}">']
    for b, c in enumerate(counts):
        bh = h * c / peak
        what = tick_labels[b] if tick_labels is not None else \
            f"{edges[b]:.3g} to {edges[b + 1]:.3g}"
        out.append(f'<rect x="{left + b * bar_w + 0.5:.1f}" y="{top + h - bh:.1f}" '
                   f'width="{max(bar_w - 1, 0.5):.1f}" height="{bh:.1f}" fill="{_BAR}">'
                   f"<title>{esc(what)}: {int(c)}</title></rect>")
    out.append(f'<line x1="{left}" y1="{top + h}" x2="{left + w}" y2="{top + h}" '
               'stroke="#333"/>')
    out.append(f'<line x1="{left}" y1="{top}" x2="{left}" y2="{top + h}" stroke="#333"/>')
    if tick_labels is not None:
        step = max(1, int(np.ceil(len(tick_labels) / 12)))
        for b in range(0, len(tick_labels), step):
            out.append(f'<text x="{left + (b + 0.5) * bar_w:.1f}" y="{top + h + 14}" '
                       f'text-anchor="middle">{esc(tick_labels[b])}</text>')
    else:
        step = max(1, int(np.ceil((len(edges) - 1) / 6)))
        for b in range(0, len(edges), step):
            out.append(f'<text x="{left + b * bar_w:.1f}" y="{top + h + 14}" '
                       f'text-anchor="middle">{edges[b]:.3g}</text>')
    for frac in (0.0, 0.5, 1.0):
        out.append(f'<text x="{left - 4}" y="{top + h - frac * h + 4:.1f}" '
                   f'text-anchor="end">{peak * frac:.0f}</text>')
    out.append(f'<text x="{left + w / 2:.1f}" y="{height - 6}" text-anchor="middle">'
               f"{esc(x_label)}</text>")
    out.append(f'<text x="12" y="{top + h / 2:.1f}" text-anchor="middle" '
               f'transform="rotate(-90 12 {top + h / 2:.1f})">{esc(y_label)}</text>')
    out.append("</svg>")
    return "".join(out)


def shared_points_svg(names: Sequence[str], shared: ArrayLike, cell: int = 0,
                      unit: str = "points") -> str:
    """The view graph as a matrix: cell (i, j) darker the more 3D points views i and j
    both see, empty where they share none.

    Parameters
    ----------
    names : sequence of str
        The views, ``V`` of them (labels along both sides).
    shared : (V, V) array_like
        Points seen by both views (the diagonal is not drawn).
    cell : int, default 0
        Cell size in CSS pixels; 0 picks one for a matrix of about 420 px.
    unit : str, default "points"
        What the counts are, in the tooltips (``"inliers"`` for verified pairs).

    Returns
    -------
    str
        An ``<svg>`` element; each cell's tooltip names the two views and the count.
    """
    shared = np.asarray(shared, dtype=np.float64)
    n = len(names)
    cell = cell or int(np.clip(420 // max(n, 1), 4, 28))
    label_w = 8 + 7 * min(max((len(s) for s in names), default=1), 16) if cell >= 10 else 8
    size = label_w + n * cell + 4
    peak = max(float(shared.max()) if shared.size else 0.0, 1.0)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{size}" '
           'role="img" aria-label="points shared by each pair of views">']
    for i in range(n):
        for j in range(n):
            if i == j or shared[i, j] <= 0:
                continue
            # A square-root scale: a pair with a tenth of the most shared points still shows.
            shade = 0.15 + 0.85 * np.sqrt(shared[i, j] / peak)
            out.append(f'<rect x="{label_w + j * cell}" y="{label_w + i * cell}" '
                       f'width="{cell - 1}" height="{cell - 1}" fill="{_BAR}" '
                       f'fill-opacity="{shade:.2f}"><title>{esc(names[i])} and '
                       f"{esc(names[j])}: {int(shared[i, j])} {esc(unit)}</title></rect>")
    out.append(f'<rect x="{label_w}" y="{label_w}" width="{n * cell}" height="{n * cell}" '
               'fill="none" stroke="#999"/>')
    if cell >= 10:
        for i, name in enumerate(names):
            short = name if len(name) <= 16 else name[:15] + "\u2026"
            y = label_w + (i + 0.5) * cell + 4
            out.append(f'<text x="{label_w - 4}" y="{y:.1f}" text-anchor="end">'
                       f"{esc(short)}</text>")
            out.append(f'<text x="{label_w + (i + 0.5) * cell + 4:.1f}" y="{label_w - 4}" '
                       f'transform="rotate(-90 {label_w + (i + 0.5) * cell + 4:.1f} '
                       f'{label_w - 4})">{esc(short)}</text>')
    out.append("</svg>")
    return "".join(out)
