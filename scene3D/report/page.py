"""One self-contained HTML page: styles, tables, embedded PNG figures, the inlined 3D view.

Everything the page shows is inside the file: figures as ``data:`` URLs, plotly.js inline,
gzip-compressed (the browser's ``DecompressionStream`` unpacks it, then the view is drawn).
A rendered page is an :class:`Html`: pieces of text, and files named where their whole
text goes (:func:`scene3D.io.export.atomic_write_pieces` copies those).
A Content-Security-Policy forbids every fetch (``default-src 'none'``), so a page that
tried to load anything would fail visibly (a console error) rather than reach the network.
"""

from __future__ import annotations

import base64
import html
import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

_CSP = ("default-src 'none'; script-src 'unsafe-inline' 'unsafe-eval'; "
        "style-src 'unsafe-inline'; img-src data: blob:; font-src data:; "
        "worker-src blob:; connect-src data: blob:")

_STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 0 auto;
       max-width: 1200px; padding: 0 1.5em 3em; color: #222; line-height: 1.45; }
h1 { font-size: 1.5em; margin: 1em 0 0.3em; } h2 { font-size: 1.2em; margin-top: 1.6em;
  border-bottom: 1px solid #ddd; padding-bottom: 0.2em; }
.lines { background: #f6f8fa; padding: 0.7em 1em; border-radius: 6px; white-space: pre-wrap;
  font-family: ui-monospace, "DejaVu Sans Mono", monospace; font-size: 0.9em; }
.verdict { padding: 0.6em 1em; border-radius: 6px; margin: 0.8em 0; }
.ok { background: #e6f4ea; border: 1px solid #a8d5b5; }
.warn { background: #fff4e5; border: 1px solid #f0c36d; }
table { border-collapse: collapse; margin: 0.5em 0; font-size: 0.92em; }
td, th { border: 1px solid #ddd; padding: 0.25em 0.7em; text-align: left; vertical-align: top; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.9em; color: #555; }
#view3d { width: 100%; height: 640px; border: 1px solid #ddd; }
.note { font-size: 0.9em; color: #555; }
.explain { font-size: 0.82em; color: #666; }
table.matrix td { font-family: ui-monospace, "DejaVu Sans Mono", monospace; text-align: right; }
.matrices { display: flex; flex-wrap: wrap; gap: 2em; }
.charts { display: flex; flex-wrap: wrap; gap: 1.5em; } .charts figure { max-width: 480px; }
td img.thumb { height: 48px; display: block; }
svg text { font-family: system-ui, sans-serif; font-size: 11px; fill: #333; }
details pre { background: #f6f8fa; padding: 0.7em; overflow-x: auto; font-size: 0.8em; }
footer { margin-top: 2em; font-size: 0.8em; color: #777; }
"""


class Markup(str):
    """HTML that a table cell takes as it is (not escaped): a thumbnail, for instance."""


def esc(text: Any) -> str:
    """HTML-escaped ``str(text)``.

    Parameters
    ----------
    text : Any
        A value.

    Returns
    -------
    str
    """
    return html.escape(str(text), quote=True)


def format_value(value: Any) -> str:
    """A number or value as the report prints it: floats to 4 significant digits with their
    trailing zeros, so that a ratio of 0.99998 reads ``1.000`` (not ``1``, an exact or whole
    value), 2.0 ``2.000`` and 1234.56 ``1235``; ints as they are.

    Parameters
    ----------
    value : Any
        None, a bool, a float, an int, a list or tuple of them, or another value.

    Returns
    -------
    str
    """
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if not math.isfinite(value):
            return "-"
        return f"{value:#.4g}".removesuffix(".")  # '#' keeps the zeros ('1235.': no dot)
    if isinstance(value, (list, tuple)):
        return ", ".join(format_value(v) for v in value)
    return str(value)


def image_data_url(data: bytes) -> str:
    """``data:image/png;base64,...`` (or ``image/jpeg`` for JPEG bytes).

    Parameters
    ----------
    data : bytes
        PNG or JPEG bytes.

    Returns
    -------
    str

    Raises
    ------
    ValueError
        For other bytes.
    """
    if data[:8] == b"\x89PNG\r\n\x1a\n":
        mime = "image/png"
    elif data[:3] == b"\xff\xd8\xff":
        mime = "image/jpeg"
    else:
        raise ValueError("a figure must be PNG or JPEG bytes")
    return f"data:{mime};base64," + base64.b64encode(data).decode("ascii")


@dataclass(frozen=True)
class Html:
    """A rendered page: pieces of text, and files whose whole text goes at their place.

    Attributes
    ----------
    pieces : tuple of (str or Path)
        In order; a :class:`~pathlib.Path` stands for that file's content (UTF-8),
        inlined verbatim.
    """

    pieces: tuple[str | Path, ...]

    def text(self) -> str:
        """The whole page as one string (the files read)."""
        return "".join(p if isinstance(p, str) else p.read_text(encoding="utf-8")
                       for p in self.pieces)

    def encoded(self) -> list[bytes | Path]:
        """The pieces for :func:`scene3D.io.export.atomic_write_pieces`: text as UTF-8 bytes,
        files as they are."""
        return [p.encode("utf-8") if isinstance(p, str) else p for p in self.pieces]


@dataclass
class Page:
    """An HTML report being assembled, section by section.

    Attributes
    ----------
    title : str
    parts : list of str
        HTML fragments, in order.
    """

    title: str
    parts: list[str] = field(default_factory=list)
    _scripts: list[str | Path] = field(default_factory=list)
    _blobs: list[tuple[str, str | Path]] = field(default_factory=list)

    def heading(self, text: str) -> None:
        """A section heading.

        Parameters
        ----------
        text : str
            Its text (escaped).
        """
        self.parts.append(f"<h2>{esc(text)}</h2>")

    def paragraph(self, text: str, css: str = "") -> None:
        """A paragraph of text.

        Parameters
        ----------
        text : str
            Its text (escaped).
        css : str, default ""
            A CSS class; "" for none.
        """
        cls = f' class="{css}"' if css else ""
        self.parts.append(f"<p{cls}>{esc(text)}</p>")

    def lines(self, lines: Iterable[str]) -> None:
        """Pre-formatted lines (what the command printed).

        Parameters
        ----------
        lines : iterable of str
            The lines (escaped).
        """
        self.parts.append(f'<div class="lines" id="summary-lines">'
                          f'{esc(chr(10).join(lines))}</div>')

    def verdict(self, good: bool, headline: str, warnings: Iterable[str] = ()) -> None:
        """A green or orange box with a headline and the warnings.

        Parameters
        ----------
        good : bool
            Green (True) or orange.
        headline : str
            The headline.
        warnings : iterable of str, default ()
            The warnings listed under it.
        """
        items = "".join(f"<li>{esc(w)}</li>" for w in warnings)
        self.parts.append(f'<div class="verdict {"ok" if good else "warn"}" id="verdict">'
                          f"<strong>{esc(headline)}</strong>"
                          + (f"<ul>{items}</ul>" if items else "") + "</div>")

    def table(self, rows: Iterable[Iterable[Any]], header: Iterable[str] | None = None,
              table_id: str = "") -> None:
        """A table; floats and ints are right-aligned, formatted by :func:`format_value`.

        Parameters
        ----------
        rows : iterable of iterable
            The cells of each row.
        header : iterable of str or None, default None
            Column headings; None for none.
        table_id : str, default ""
            The element's id; "" for none.
        """
        out = [f'<table{f" id={chr(34)}{esc(table_id)}{chr(34)}" if table_id else ""}>']
        if header is not None:
            out.append("<tr>" + "".join(f"<th>{esc(h)}</th>" for h in header) + "</tr>")
        for row in rows:
            cells = []
            for v in row:
                if isinstance(v, Markup):
                    cells.append(f"<td>{v}</td>")
                    continue
                num = isinstance(v, (int, float)) and not isinstance(v, bool)
                cells.append(f'<td{" class=num" if num else ""}>{esc(format_value(v))}</td>')
            out.append("<tr>" + "".join(cells) + "</tr>")
        out.append("</table>")
        self.parts.append("".join(out))

    def key_values(self, values: Mapping[str, Any], table_id: str = "") -> None:
        """A two-column table of names and values.

        Parameters
        ----------
        values : mapping of str to Any
            Values by name.
        table_id : str, default ""
            The element's id; "" for none.
        """
        self.table(((k, v) for k, v in values.items()), table_id=table_id)

    def quantities(self, rows: Iterable[tuple[str, str, str]], table_id: str = "") -> None:
        """A table of named values with their units, each name with its explanation on a
        small line below it (and as the row's tooltip).

        Parameters
        ----------
        rows : iterable of (str, str, str)
            ``(label, value with unit, explanation)``
            (:func:`scene3D.report.wording.quantity_rows`).
        table_id : str, default ""
            The element's id; "" for none.
        """
        out = [f'<table{f" id={chr(34)}{esc(table_id)}{chr(34)}" if table_id else ""}>']
        for label, value, explain in rows:
            note = f'<div class="explain">{esc(explain)}</div>' if explain else ""
            tip = f' title="{esc(explain)}"' if explain else ""
            out.append(f"<tr{tip}><td>{esc(label)}{note}</td><td class=num>{esc(value)}</td>"
                       "</tr>")
        out.append("</table>")
        self.parts.append("".join(out))

    def matrices(self, named: Mapping[str, list[list[str]]], note: str = "") -> None:
        """Small matrices side by side, each under its name (R, t, K).

        Parameters
        ----------
        named : mapping of str to list of list of str
            Caption -> rows of formatted numbers.
        note : str, default ""
            A line under them; "" for none.
        """
        boxes = []
        for name, rows in named.items():
            body = "".join("<tr>" + "".join(f"<td>{esc(v)}</td>" for v in row) + "</tr>"
                           for row in rows)
            boxes.append(f'<div><div>{esc(name)}</div><table class="matrix">{body}</table>'
                         "</div>")
        self.parts.append('<div class="matrices">' + "".join(boxes) + "</div>")
        if note:
            self.paragraph(note, "note")

    def svg(self, svg: str, caption: str) -> None:
        """An inline SVG drawing (a chart made by :mod:`scene3D.report.charts`) with a
        caption.

        Parameters
        ----------
        svg : str
            The ``<svg>`` element, its text escaped by its maker.
        caption : str
            The caption (escaped).
        """
        self.parts.append(f"<figure>{svg}<figcaption>{esc(caption)}</figcaption></figure>")

    def open_row(self) -> None:
        """Start a row of side-by-side figures (closed by :meth:`close_row`)."""
        self.parts.append('<div class="charts">')

    def close_row(self) -> None:
        """End the row :meth:`open_row` started."""
        self.parts.append("</div>")

    def figure(self, image: bytes, caption: str, alt: str = "") -> None:
        """An embedded figure (PNG or JPEG bytes).

        Parameters
        ----------
        image : bytes
            PNG or JPEG bytes.
        caption : str
            The caption.
        alt : str, default ""
            Alternative text; "" for the caption.
        """
        self.parts.append(f'<figure><img src="{image_data_url(image)}" '
                          f'alt="{esc(alt or caption)}">'
                          f"<figcaption>{esc(caption)}</figcaption></figure>")

    def view3d(self, plotly_js: Path, figure_json: str, notes: Iterable[str] = ()) -> None:
        """The interactive 3D view: the file ``plotly_js`` (plotly.min.js) inlined once,
        gzip-compressed and unpacked by the browser, and the figure as JSON data.

        Parameters
        ----------
        plotly_js : Path
            The plotly.min.js file.
        figure_json : str
            The figure as JSON (:func:`scene3D.report.viewer.scene_figure_json`).
        notes : iterable of str, default ()
            Notes shown above the view.
        """
        from .viewer import compressed_plotly_js

        for note in notes:
            self.paragraph(note, "note")
        self.parts.append('<div id="view3d"></div>')
        self.parts.append(f'<script type="application/json" id="view3d-data">{figure_json}'
                          "</script>")
        self._blobs.append(("plotly-gzip", compressed_plotly_js(plotly_js)))
        # Unpacked in the browser (no fetch: the bytes are in the page), then run as a
        # global script (indirect eval) so that it defines window.Plotly.
        self._scripts.append(
            "(async function () {\n"
            "  var b64 = document.getElementById('plotly-gzip').textContent;\n"
            "  var bytes = Uint8Array.from(atob(b64), function (c) { return c.charCodeAt(0); });\n"
            "  var stream = new Blob([bytes]).stream()"
            ".pipeThrough(new DecompressionStream('gzip'));\n"
            "  (0, eval)(await new Response(stream).text());\n"
            "  var fig = JSON.parse(document.getElementById('view3d-data').textContent);\n"
            "  Plotly.newPlot('view3d', fig.data, fig.layout,\n"
            "                 {displaylogo: false, responsive: true, scrollZoom: true});\n"
            "})();")

    def raw_json(self, obj: Any, summary: str = "All numbers (JSON)") -> None:
        """A collapsed block with ``obj`` as indented JSON.

        Parameters
        ----------
        obj : Any
            JSON-serialisable values (others as ``str``).
        summary : str, default "All numbers (JSON)"
            The block's title.
        """
        text = json.dumps(obj, indent=2, default=str, allow_nan=True)
        self.parts.append(f"<details><summary>{esc(summary)}</summary><pre>{esc(text)}</pre>"
                          "</details>")

    def render(self, footer: str = "") -> Html:
        """The whole page.

        Parameters
        ----------
        footer : str, default ""
            A footer line; "" for none.

        Returns
        -------
        Html
        """
        pieces: list[str | Path] = [
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f'<meta http-equiv="Content-Security-Policy" content="{_CSP}">\n'
            '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
            f"<title>{esc(self.title)}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n"
            f"<h1>{esc(self.title)}</h1>\n" + "\n".join(self.parts) + "\n"
            + (f"<footer>{esc(footer)}</footer>\n" if footer else "")
        ]
        for blob_id, blob in self._blobs:  # data for the scripts (text, or a file's text)
            pieces += [f'<script type="application/octet-stream" id="{blob_id}">', blob,
                       "</script>\n"]
        for script in self._scripts:
            pieces += ["<script>", script, "</script>\n"]
        pieces.append("</body>\n</html>\n")
        return Html(tuple(pieces))
