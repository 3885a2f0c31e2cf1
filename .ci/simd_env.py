"""Print the environment that holds NumPy's and OpenCV's SIMD kernels to a lower level.

    env $(python .ci/simd_env.py avx2) python -m pytest -m realdata

``avx2``: the kernels of an x86-64 machine without AVX-512 (most laptops and many cloud
machines); ``sse4``: those of one without AVX either. Each library picks its kernels for
the CPU at import time, unless told not to (``NPY_DISABLE_CPU_FEATURES``,
``OPENCV_CPU_DISABLE``); a result that changes between them is decided by floating point,
not by our code (docs/contributing.md, "Machines and versions"). The names to disable
are read from the NumPy that runs this script (they changed with NumPy 2.4: ``X86_V3``
and ``X86_V4`` in place of ``AVX2``, ``AVX512F``, ...), so run it with the environment's
own interpreter. Prints nothing on a CPU that is not x86-64, or where nothing it has is
above the level.
"""

from __future__ import annotations

import platform
import sys

#: What each level keeps, in NumPy's names (old and new) and in OpenCV's.
KEEP_NUMPY = {
    "sse4": {"SSE", "SSE2", "SSE3", "SSSE3", "SSE41", "POPCNT", "SSE42", "X86_V2"},
}
KEEP_NUMPY["avx2"] = KEEP_NUMPY["sse4"] | {"AVX", "F16C", "FMA3", "AVX2", "X86_V3"}
KEEP_OPENCV = {"sse4": {"SSE", "SSE2", "SSE3", "SSSE3", "SSE4.1", "POPCNT", "SSE4.2"}}
KEEP_OPENCV["avx2"] = KEEP_OPENCV["sse4"] | {"AVX", "FP16", "AVX2", "FMA3"}


def held_environment(level: str) -> dict[str, str]:
    """The variables that hold both libraries to ``level`` ("avx2" or "sse4")."""
    if level not in KEEP_NUMPY:
        raise SystemExit(f"simd_env.py: the level must be one of {', '.join(KEEP_NUMPY)}, "
                         f"got {level!r}")
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return {}
    import cv2
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

    # Only what this CPU has: a library told to disable a feature the CPU lacks says so
    # on stderr at every import (OpenCV: "Trying to disable unavailable CPU feature"),
    # which the tests of one-line errors read as a second line.
    numpy_off = [name for name in __cpu_dispatch__
                 if name not in KEEP_NUMPY[level] and __cpu_features__.get(name)]
    # "SSE SSE2 SSE3 *SSE4.1 ... *AVX512-SKX?": the baseline, then the dispatched ones
    # (*), those this CPU lacks marked with '?'.
    opencv = [name.strip("*") for name in cv2.getCPUFeaturesLine().split()
              if name.startswith("*") and not name.endswith("?")]
    opencv_off = [name for name in opencv if name not in KEEP_OPENCV[level]]
    held = {}
    if numpy_off:
        held["NPY_DISABLE_CPU_FEATURES"] = ",".join(numpy_off)
    if opencv_off:
        held["OPENCV_CPU_DISABLE"] = ",".join(opencv_off)
    return held


if __name__ == "__main__":
    if len(sys.argv) != 2:
        raise SystemExit("usage: python .ci/simd_env.py {avx2,sse4}")
    print(" ".join(f"{name}={value}" for name, value in held_environment(sys.argv[1]).items()))
