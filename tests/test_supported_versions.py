"""The versions we say we support are the ones CI tests: pyproject.toml's lower bounds are
the pins of .ci/oldest-constraints.txt, and CI's environment for them runs on this
machine's kernels held lower (.ci/simd_env.py)."""

import re
import subprocess
import sys

import pytest
from packaging.requirements import Requirement
from packaging.version import Version

from .conftest import REPO

tomllib = pytest.importorskip("tomllib")  # Python 3.11+


def _requirements() -> dict[str, Requirement]:
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    listed = project["dependencies"] + [r for extra in ("dev", "distributed", "heic")
                                        for r in project["optional-dependencies"][extra]]
    return {Requirement(r).name.lower(): Requirement(r) for r in listed}


def _oldest_pins() -> dict[str, Version]:
    pins = {}
    for line in (REPO / ".ci" / "oldest-constraints.txt").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, version = line.split("==")
            pins[name.strip().lower()] = Version(version.strip())
    return pins


def _lower_bound(requirement: Requirement) -> Version | None:
    bounds = [Version(s.version) for s in requirement.specifier if s.operator == ">="]
    return max(bounds) if bounds else None


def test_every_runtime_dependency_has_its_oldest_version_pinned():
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    runtime = {Requirement(r).name.lower() for r in project["dependencies"]}
    assert runtime <= set(_oldest_pins()), runtime - set(_oldest_pins())


@pytest.mark.parametrize("name", sorted(_oldest_pins()))
def test_each_pin_is_the_lower_bound_the_range_admits(name):
    """The pin is in the range, and is its lower bound (to as many places as the bound
    gives: '>=5.0' is pinned as 5.0.0.93, the first 5.0 release)."""
    requirements = _requirements()
    if name == "distributed":  # comes with dask[distributed], at dask's version
        requirement = requirements["dask"]
    else:
        assert name in requirements, f"{name} is pinned but not a dependency"
        requirement = requirements[name]
    pin = _oldest_pins()[name]
    assert requirement.specifier.contains(pin, prereleases=False), (requirement, pin)
    bound = _lower_bound(requirement)
    assert bound is not None, f"{requirement} has no lower bound to pin"
    assert pin.release[:len(bound.release)] == bound.release, (requirement, pin)


def test_opencv_is_held_below_its_next_minor_release():
    """A minor release of OpenCV can move RANSAC's, SIFT's and the solvers' results: the
    range admits only the releases CI has run."""
    opencv = _requirements()["opencv-contrib-python-headless"]
    assert any(s.operator == "<" for s in opencv.specifier), opencv


@pytest.mark.skipif(not re.match(r"(x86_64|amd64)$", __import__("platform").machine(), re.I),
                    reason="SIMD levels are held on x86-64 only")
@pytest.mark.parametrize("level", ["avx2", "sse4"])
def test_the_held_levels_leave_no_kernel_above_them(level):
    """.ci/simd_env.py's variables, given to a new interpreter, leave NumPy and OpenCV no
    kernel above the level (OpenCV marks a disabled one with '?')."""
    held = subprocess.run([sys.executable, str(REPO / ".ci" / "simd_env.py"), level],
                          capture_output=True, text=True, check=True).stdout.split()
    env = dict(item.split("=", 1) for item in held)
    probe = ("import cv2\n"
             "from numpy._core._multiarray_umath import __cpu_dispatch__ as d, "
             "__cpu_features__ as f\n"
             "print(' '.join(n for n in d if f[n]))\n"
             "print(cv2.getCPUFeaturesLine())\n")
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, env={**__import__("os").environ, **env})
    # A feature held off that this CPU lacks makes OpenCV warn at every import.
    assert run.stderr == ""
    numpy_on, opencv_line = run.stdout.splitlines()
    above = r"512|X86_V4" if level == "avx2" else r"512|X86_V[34]|AVX|FMA|F16C"
    assert not [name for name in numpy_on.split() if re.search(above, name)], numpy_on
    on = {name.strip("*") for name in opencv_line.split() if not name.endswith("?")}
    assert not on & {"AVX512-SKX", "AVX512-CLX", "AVX512-ICL", "AVX_VNNI"}
    if level == "sse4":
        assert not on & {"AVX", "AVX2", "FP16", "FMA3"}
