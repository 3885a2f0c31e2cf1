"""scene3D.errors: the helpers that messages share, and the flags that only the commands name."""

import ast
import pickle
import re
from pathlib import Path

import pytest

from scene3D.cli.common import with_flag_hint
from scene3D.errors import EngineError, ReconstructionError, plural
from scene3D.report.viewer import MissingViewerError


@pytest.mark.parametrize("count, noun, expected", [
    (1, "pose", "1 pose"),
    (2, "pose", "2 poses"),
    (0, "pose", "0 poses"),
    (1, "inner corner", "1 inner corner"),
    (4, "inner corner", "4 inner corners"),
    (43, "pairs task", "43 pairs tasks"),
])
def test_plural_puts_the_count_before_the_noun_and_an_s_after_all_but_one(count, noun,
                                                                          expected):
    assert plural(count, noun) == expected


def test_library_messages_name_no_command_line_flag():
    """Outside scene3D.cli no string that is not a docstring names a flag ("--dense"): the
    library raises a typed error with a reason and the command adds the flag."""
    package = Path(__file__).resolve().parents[1] / "scene3D"
    flag = re.compile(r"(?<![\w-])--[a-z][a-z-]*")
    found = []
    for path in sorted(package.rglob("*.py")):
        if "cli" in path.relative_to(package).parts:
            continue
        tree = ast.parse(path.read_text())
        docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                      if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef,
                                           ast.AsyncFunctionDef))
                      and node.body and isinstance(node.body[0], ast.Expr)
                      and isinstance(node.body[0].value, ast.Constant)}
        for node in ast.walk(tree):
            if (isinstance(node, ast.Constant) and isinstance(node.value, str)
                    and id(node) not in docstrings and flag.search(node.value)):
                found.append(f"{path.relative_to(package)}:{node.lineno}: {node.value!r}")
    assert found == []


@pytest.mark.parametrize("exc, printed", [
    (ReconstructionError("no_dense_range", "dense matching cannot serve this pair; the "
                         "sparse result does not need it"),
     "dense matching cannot serve this pair; the sparse result does not need it "
     "(run without --dense)"),
    (ReconstructionError("no_dense_points", "no disparity"), "no disparity (run without --dense)"),
    (EngineError("no worker; start one with 'dask worker ADDRESS'", "no_workers"),
     "no worker; start one with 'dask worker ADDRESS', or run without --scheduler"),
    (EngineError("task 3 was cancelled: gone", "task_cancelled"), "task 3 was cancelled: gone"),
    (ReconstructionError("too_few_matches", "too few matches", matches=3),
     "too few matches (matches=3)"),
])
def test_a_command_adds_the_flag_that_avoids_a_library_error(exc, printed):
    assert with_flag_hint(exc) == printed


def test_errors_keep_their_reason_through_pickling():
    for exc in (EngineError("gone", "scheduler_lost"),
                MissingViewerError("no plotly", "no_plotly_js")):
        copy = pickle.loads(pickle.dumps(exc))
        assert (type(copy), str(copy), copy.reason) == (type(exc), str(exc), exc.reason)
