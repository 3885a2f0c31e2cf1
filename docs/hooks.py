"""MkDocs hook: put each command's real ``--help`` into the pages when the site is built.

A line ``<!-- help: scene3d reconstruct -->`` (or ``chapter4.py``, ``calibrate.py``,
``scene3d``, ``scene3d COMMAND``) is replaced by that command's ``--help`` text, 100
columns wide, so that the command-line reference cannot drift from the code. An
unknown command fails the build.
"""

from __future__ import annotations

import contextlib
import io
import os
import re

MARKER = re.compile(r"^<!-- help: (?P<command>[\w.\- ]+?) -->$", re.MULTILINE)


def _help_text(command: str) -> str:
    from scene3D import cli
    from scene3D.cli import calibrate, chapter4

    words = command.split()
    entry = {"chapter4.py": chapter4.main, "calibrate.py": calibrate.main,
             "scene3d": cli.main}.get(words[0])
    if entry is None or (words[0] != "scene3d" and len(words) > 1):
        raise ValueError(f"hooks.py: no command {command!r} for a help marker")
    buffer = io.StringIO()
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"
    try:
        with contextlib.redirect_stdout(buffer):
            try:
                code = entry([*words[1:], "--help"])
            except SystemExit as exc:  # argparse's --help
                code = exc.code or 0
    finally:
        if old is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = old
    if code != 0:
        raise ValueError(f"hooks.py: '{command} --help' exited with {code}")
    return buffer.getvalue().rstrip()


def on_page_markdown(markdown: str, **kwargs) -> str:
    def replace(match: re.Match) -> str:
        command = match["command"]
        return f"```text\n$ {command} --help\n{_help_text(command)}\n```"

    return MARKER.sub(replace, markdown)
