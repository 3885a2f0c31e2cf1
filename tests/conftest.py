"""Shared fixtures: where the real data live, synthetic scenes with known geometry."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

from scene3D.evaluation import synthetic  # noqa: E402
from scene3D.io.datasets import default_data_root  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def pytest_report_header(config) -> list[str]:
    """What the results depend on beyond our code: the versions of the numerical
    libraries and the SIMD kernels they dispatch to on this CPU (a pose on a knife edge
    can come out otherwise on another machine: docs/contributing.md, "Machines and
    versions")."""
    import platform

    import cv2

    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # numpy's private layout may move; the header is for reading
        __cpu_dispatch__, __cpu_features__ = [], {}
    numpy_simd = [name for name in __cpu_dispatch__ if __cpu_features__.get(name)]
    cpuinfo = Path("/proc/cpuinfo")
    model = next((line.split(":", 1)[1].strip() for line in (
        cpuinfo.read_text().splitlines() if cpuinfo.exists() else ())
        if line.startswith("model name")), platform.processor())
    held = [f"{name}={os.environ[name]!r}" for name in ("NPY_DISABLE_CPU_FEATURES",
                                                        "OPENCV_CPU_DISABLE")
            if os.environ.get(name)]
    versions = [f"numpy {np.__version__}", f"opencv {cv2.__version__}",
                f"matplotlib {matplotlib.__version__}"]
    for name in ("scipy", "PIL", "plotly"):
        try:
            versions.append(f"{name} {__import__(name).__version__}")
        except ImportError:
            versions.append(f"{name} not installed")
    simd = " ".join(numpy_simd) or "its baseline only"
    return [f"scene3D against: {', '.join(versions)}",
            f"CPU: {platform.machine()} {model}, {os.cpu_count()} cores; numpy dispatches to "
            f"{simd}; OpenCV: {cv2.getCPUFeaturesLine()} (* dispatched, ? disabled)"
            + (f"; held by {', '.join(held)}" if held else "")]


#: Fixtures that read the shared photos (SCENE3D_DATA): their tests are marked
#: ``realdata``, the ones whose outcomes a CPU's floating point or a dependency's release
#: can move (``pytest -m realdata`` runs only them, e.g. on kernels held lower).
REAL_DATA_FIXTURES = {"data_root"}


def pytest_collection_modifyitems(config, items) -> None:
    for item in items:
        if REAL_DATA_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.realdata)


def _data_root() -> Path | None:
    root = default_data_root()
    # Absolute, so a test that links to a photo or runs a command elsewhere still finds it
    # when SCENE3D_DATA is relative.
    return root.resolve() if root is not None and root.is_dir() else None


@pytest.fixture(scope="session")
def data_root() -> Path:
    """``$SCENE3D_DATA`` (default ../shared/data). Missing data skip locally, fail in CI."""
    root = _data_root()
    if root is None:
        if os.environ.get("CI"):
            pytest.fail("SCENE3D_DATA is not set and ../shared/data does not exist")
        pytest.skip("real data not available: set SCENE3D_DATA (see README)")
    return root


@pytest.fixture(scope="session")
def fountain(data_root: Path) -> Path:
    return data_root / "fountain-P11"


def _scene(data_root: Path, name: str) -> Path:
    """A shared Strecha scene; skipped where it is missing (a failure in CI)."""
    path = data_root / name
    if not path.is_dir():
        if os.environ.get("CI"):
            pytest.fail(f"{name} is missing from {data_root}")
        pytest.skip(f"{name} not found in {data_root}")
    return path


@pytest.fixture(scope="session")
def castle(data_root: Path) -> Path:
    """castle-P19 (Strecha): a courtyard of repeated windows."""
    return _scene(data_root, "castle-P19")


@pytest.fixture(scope="session")
def herz_jesus(data_root: Path) -> Path:
    """Herz-Jesus-P8 (Strecha): a church facade, nearly planar in parts."""
    return _scene(data_root, "Herz-Jesus-P8")


@pytest.fixture(scope="session")
def chessboards(data_root: Path) -> Path:
    return data_root / "chessboard"


@pytest.fixture(scope="session")
def camera() -> np.ndarray:
    return synthetic.asymmetric_camera()


@pytest.fixture(scope="session")
def true_pose() -> tuple[np.ndarray, np.ndarray]:
    return synthetic.asymmetric_pose()


@pytest.fixture(scope="session")
def rendered_pair(camera, true_pose):
    """Two renderings of the box scene: (img1, img2, K, R_true, t_true)."""
    R, t = true_pose
    img1, _ = synthetic.render_planes(camera, np.eye(3), np.zeros(3))
    img2, _ = synthetic.render_planes(camera, R, t)
    return img1, img2, camera, R, t


@pytest.fixture(scope="session")
def rotated_pair(camera, true_pose):
    """The box scene seen from one centre, the camera only turned."""
    R, _ = true_pose
    img1, _ = synthetic.render_planes(camera, np.eye(3), np.zeros(3))
    img2, _ = synthetic.render_planes(camera, R, np.zeros(3))
    return img1, img2, camera
