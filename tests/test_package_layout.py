"""The package's layout (issue #49): the old module paths still import, warn and give the moved
module's objects; nothing in the repository imports them; at most eight modules stay at the top
level; and the import graph between scene3D's modules has no cycle."""

import ast
import importlib
import json
import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "scene3D"

#: The modules moved into subpackages (old -> new, under scene3D), whose old paths are shims
#: that warn: they go in the next release.
MOVED = {
    "camera": "geometry.camera",
    "epipolar": "geometry.epipolar",
    "pose": "geometry.pose",
    "triangulation": "geometry.triangulation",
    "rectification": "geometry.rectification",
    "intrinsics_prior": "geometry.intrinsics_prior",
    "uncertainty": "optim.uncertainty",
    "refinement": "optim.refinement",
    "schur": "optim.schur",
    "bundle": "optim.bundle",
    "bundle_two_view": "optim.bundle_two_view",
    "degeneracy": "twoview.degeneracy",
    "essential_fit": "twoview.essential_fit",
    "focal_fit": "twoview.focal_fit",
    "distortion_fit": "twoview.distortion_fit",
    "flow_check": "twoview.flow_check",
    "imageio": "io.images",
    "image_integrity": "io.image_integrity",
    "exif": "io.exif",
    "calibration_io": "io.calibration",
    "export": "io.export",
    "datasets": "io.datasets",
    "calibration_uncertainty": "calibration.uncertainty",
    "drawing": "viz.drawing",
    "plotting": "viz.plotting",
    "synthetic": "evaluation.synthetic",
}
#: The modules that a package of the same name replaced, and the modules the old one's names
#: now live in: the package re-exports their public names (no shim, no warning).
REPLACED = {
    "geometry": ("geometry.conventions",),
    "features": ("features.matching",),
    "calibration": ("calibration.board", "calibration.solve"),
    "evaluation": ("evaluation.poses",),
}
MAX_TOP_LEVEL_MODULES = 8
#: The most lines of any module under scene3D/ (issue #49), shims, packages and CLI included.
MAX_MODULE_LINES = 600
SKIPPED_FOLDERS = {".git", ".venv", "venv", "site", "out", "build", "dist", "__pycache__"}


def public_names(module) -> list[str]:
    """The names a module offers: its ``__all__``, what it defines, and what it takes from
    other scene3D modules (not the third-party names it imports)."""
    tree = ast.parse(Path(module.__file__).read_text())
    own = set(getattr(module, "__all__", ()))
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            own.add(node.name)
        elif isinstance(node, ast.Assign):
            own |= {t.id for t in node.targets if isinstance(t, ast.Name)}
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            own.add(node.target.id)
    names = []
    for name, value in vars(module).items():
        if name.startswith("_") or name == "logger" or isinstance(value, type(sys)):
            continue
        if name in own or (getattr(value, "__module__", None) or "").startswith("scene3D"):
            names.append(name)
    return sorted(names)


def test_every_old_path_warns_once_with_its_new_path():
    """Each shim, imported for the first time in a fresh interpreter, gives exactly one
    DeprecationWarning of scene3D's, "scene3D.OLD moved to scene3D.NEW", pointing at the
    line that imported it; imported again, none. Only scene3D's own warnings count: an old
    matplotlib under a new pyparsing warns of pyparsing's renames on import, which is
    neither ours nor wrong."""
    code = ("import json, sys, warnings\n"
            "out = {}\n"
            f"for old in {sorted(MOVED)!r}:\n"
            "    counts = []\n"
            "    for _ in range(2):\n"
            "        with warnings.catch_warnings(record=True) as caught:\n"
            "            warnings.simplefilter('always')\n"
            "            exec(compile('import scene3D.' + old, '<importer>', 'exec'))\n"
            "        counts.append([[str(w.message), w.filename] for w in caught\n"
            "                       if issubclass(w.category, DeprecationWarning)\n"
            "                       and str(w.message).startswith('scene3D.')])\n"
            "    out[old] = counts\n"
            "json.dump(out, sys.stdout)\n")
    proc = run_python(code)
    assert proc.returncode == 0, proc.stderr
    seen = json.loads(proc.stdout)
    expected = {old: [[[f"scene3D.{old} moved to scene3D.{new}", "<importer>"]], []]
                for old, new in MOVED.items()}
    assert seen == expected


@pytest.mark.parametrize("old", sorted(MOVED))
def test_an_old_path_is_documented_as_deprecated_and_gives_the_moved_module_objects(
        old, monkeypatch):
    new = importlib.import_module(f"scene3D.{MOVED[old]}")
    monkeypatch.delitem(sys.modules, f"scene3D.{old}", raising=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the test above counts them
        shim = importlib.import_module(f"scene3D.{old}")
    assert shim.__doc__.startswith(f"Deprecated: moved to :mod:`scene3D.{MOVED[old]}`.")
    names = public_names(new)
    assert names
    assert [n for n in names if getattr(shim, n, None) is not getattr(new, n)] == []


@pytest.mark.parametrize("old", sorted(REPLACED))
def test_a_package_that_replaced_a_module_offers_its_names(old):
    package = importlib.import_module(f"scene3D.{old}")
    assert hasattr(package, "__path__") and not (PACKAGE / f"{old}.py").exists()
    for name in REPLACED[old]:
        module = importlib.import_module(f"scene3D.{name}")
        names = public_names(module)
        assert names
        assert [n for n in names if getattr(package, n, None) is not getattr(module, n)] == []


def test_the_new_paths_import_without_a_deprecation_warning():
    """No module imports a moved one's old path (its shim warns "scene3D.x moved to ...").
    Only scene3D's own deprecations count: an old matplotlib under a new pyparsing warns
    of pyparsing's renames on import, which is neither ours nor wrong."""
    modules = sorted(module_name(p) for p in package_files()
                     if not is_shim(p) and p.name != "__main__.py")  # __main__ runs the command
    code = ("import importlib, warnings\n"
            "with warnings.catch_warnings(record=True) as caught:\n"
            "    warnings.simplefilter('always')\n"
            f"    for m in {modules!r}:\n"
            "        importlib.import_module(m)\n"
            "ours = [str(w.message) for w in caught if issubclass(w.category, "
            "DeprecationWarning) and 'scene3D' in str(w.message)]\n"
            "raise SystemExit('; '.join(ours) or None)\n")
    proc = run_python(code)
    assert proc.returncode == 0, proc.stderr
    # The check sees a shim's warning:
    proc = run_python(code.replace(repr(modules), repr(["scene3D.camera"])))
    assert proc.returncode == 1 and "scene3D.camera moved to" in proc.stderr


def test_at_most_eight_modules_stay_at_the_top_level():
    top = sorted(p.stem for p in PACKAGE.glob("*.py"))
    shims = [name for name in top if name in MOVED]
    assert len(top) - len(shims) <= MAX_TOP_LEVEL_MODULES, top
    for name in MOVED:  # each old path is a shim and nothing more
        assert is_shim(PACKAGE / f"{name}.py"), name


def test_no_module_is_over_the_line_limit():
    assert "multiview/pipeline.py" in long_modules(PACKAGE, 0)  # the walk sees subpackages
    assert long_modules(PACKAGE, MAX_MODULE_LINES) == {}


def test_the_line_limit_check_sees_a_long_module(tmp_path):
    """A module one line over the limit, at the top or in a subpackage, is named; one at
    the limit is not."""
    (tmp_path / "sub").mkdir()
    for name, lines in [("long.py", MAX_MODULE_LINES + 1), ("short.py", MAX_MODULE_LINES),
                        ("sub/deep.py", MAX_MODULE_LINES + 1)]:
        (tmp_path / name).write_text("x = 1\n" * lines)
    assert long_modules(tmp_path, MAX_MODULE_LINES) == {"long.py": 601, "sub/deep.py": 601}


def test_nothing_in_the_repository_imports_an_old_path():
    old = {f"scene3D.{name}" for name in MOVED}
    dotted = re.compile(r"(?<![\w.])scene3D\.(" + "|".join(MOVED) + r")(?![\w])")
    found = []
    for path, source in repository_sources():
        in_package = PACKAGE in path.parents
        for node in ast.walk(ast.parse(source)):
            for target in imported_modules(node, module_name(path) if in_package else "",
                                           path.name == "__init__.py"):
                if target in old or any(target.startswith(f"{o}.") for o in old):
                    found.append(f"{path.relative_to(REPO)}:{node.lineno}: {target}")
        for lineno, line in enumerate(source.splitlines(), 1):  # patch targets, loggers
            if dotted.search(line):
                found.append(f"{path.relative_to(REPO)}:{lineno}: {line.strip()}")
    assert found == []


def test_the_imports_between_scene3D_modules_make_no_cycle():
    graph = import_graph()
    assert "scene3D.geometry.conventions" in graph["scene3D.geometry"]
    state: dict[str, int] = {}  # 1 on the path, 2 done
    path: list[str] = []

    def visit(node: str) -> None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                cycle = path[path.index(nxt):] + [nxt]
                pytest.fail("import cycle: " + " -> ".join(cycle))
            if nxt not in state:
                visit(nxt)
        path.pop()
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node)


# --- helpers -------------------------------------------------------------------------------

def run_python(code: str) -> subprocess.CompletedProcess:
    """``code`` run by a fresh interpreter in the repository (nothing imported yet)."""
    return subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                          text=True)


def package_files() -> list[Path]:
    return sorted(p for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def long_modules(package: Path, limit: int) -> dict[str, int]:
    """The modules under ``package`` of more than ``limit`` lines: path (relative to it)
    -> number of lines."""
    lengths = {p.relative_to(package).as_posix(): len(p.read_text().splitlines())
               for p in sorted(package.rglob("*.py")) if "__pycache__" not in p.parts}
    return {name: n for name, n in lengths.items() if n > limit}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def is_shim(path: Path) -> bool:
    """A docstring, imports from the new module and of :func:`scene3D.errors.warn_moved`,
    and one call of it with the module's name and the new path."""
    if path.parent != PACKAGE or path.stem not in MOVED:
        return False
    new = f"{MOVED[path.stem]}"
    body = ast.parse(path.read_text()).body
    kinds = []
    for node in body:
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
            kinds.append("doc")
        elif (isinstance(node, ast.ImportFrom) and node.level == 1 and node.module == "errors"
              and [a.name for a in node.names] == ["warn_moved"]):
            kinds.append("import")
        elif isinstance(node, ast.ImportFrom) and node.level == 1 and node.module == new:
            kinds.append("from")
        elif (isinstance(node, ast.Expr) and isinstance(node.value, ast.Call)
              and ast.unparse(node.value) == f"warn_moved(__name__, 'scene3D.{new}')"):
            kinds.append("warn")
        else:
            return False
    return (kinds[0] == "doc" and kinds[-1] == "warn" and kinds.count("warn") == 1
            and kinds.count("import") == 1 and "from" in kinds)


def repository_sources() -> list[tuple[Path, str]]:
    """Every .py file of the repository but the shims and this test, and the notebooks' code."""
    out = []
    for path in sorted(REPO.rglob("*.py")):
        rel = path.relative_to(REPO).parts
        if SKIPPED_FOLDERS & set(rel[:-1]) or any(p.startswith(".") for p in rel[:-1]):
            continue
        if is_shim(path) or path == Path(__file__).resolve():
            continue
        out.append((path, path.read_text()))
    for path in sorted((REPO / "examples").glob("*.ipynb")):
        cells = json.loads(path.read_text())["cells"]
        code = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
        code = "\n".join("pass" if line.lstrip().startswith(("%", "!")) else line
                         for line in code.splitlines())
        out.append((path, code))
    return out


def imported_modules(node: ast.AST, importer: str, is_package: bool) -> list[str]:
    """The absolute names of the modules an import statement loads (for ``from P import x``
    both ``P`` and ``P.x``, which may be a submodule)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if not isinstance(node, ast.ImportFrom):
        return []
    if node.level:
        parts = importer.split(".") if is_package else importer.split(".")[:-1]
        parts = parts[: len(parts) - (node.level - 1)]
        base = ".".join(parts + ([node.module] if node.module else []))
    else:
        base = node.module or ""
    return [base] + [f"{base}.{a.name}" for a in node.names]


def type_checking_imports(tree: ast.Module) -> set[int]:
    """The ids of the import nodes under ``if TYPE_CHECKING:`` (they never run)."""
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING":
            skip |= {id(n) for stmt in node.body for n in ast.walk(stmt)}
    return skip


def import_graph() -> dict[str, set[str]]:
    """Module -> the scene3D modules its imports load, shims left out (nothing imports them).

    An import of ``a.b.c`` runs the ``__init__`` of ``a`` and ``a.b`` first, so it depends on
    those too, except on the importer's own packages, which are already being imported. A
    package's ``__init__`` depends on the submodules it imports. Imports under
    ``TYPE_CHECKING`` do not count; those inside functions do."""
    files = {module_name(p): p for p in package_files() if not is_shim(p)}
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        tree = ast.parse(path.read_text())
        skip = type_checking_imports(tree)
        own = {".".join(name.split(".")[:i]) for i in range(1, name.count(".") + 1)}
        if path.name == "__init__.py":
            own.add(name)
        edges = set()
        for node in ast.walk(tree):
            if id(node) in skip:
                continue
            for target in imported_modules(node, name, path.name == "__init__.py"):
                if target not in files:
                    continue
                parts = target.split(".")
                for i in range(1, len(parts) + 1):
                    prefix = ".".join(parts[:i])
                    if prefix in files and (prefix not in own or prefix == target):
                        edges.add(prefix)
        edges.discard(name)
        graph[name] = edges
    return graph


def test_default_data_root_is_beside_the_checkout(monkeypatch):
    """Without ``$SCENE3D_DATA`` the data are ``shared/data`` beside the checkout, wherever
    the module that finds them sits in the package (a move once made it look inside it)."""
    from scene3D.io.datasets import default_data_root

    monkeypatch.delenv("SCENE3D_DATA", raising=False)
    beside = Path(__file__).resolve().parents[2] / "shared" / "data"
    assert default_data_root() == (beside if beside.is_dir() else None)
    monkeypatch.setenv("SCENE3D_DATA", "/somewhere/else")
    assert default_data_root() == Path("/somewhere/else")
