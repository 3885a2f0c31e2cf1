"""glibc malloc settings that keep freed memory for reuse (scene3D.memory)."""

import os
import subprocess
import sys

import pytest

from scene3D.memory import KEPT_BYTES, malloc_environment, user_tuned_malloc

#: Allocates ``blocks`` blocks of ``mib`` MiB, frees them, three times, and prints the
#: pages each round faulted in: run in a process started by one that called
#: keep_freed_memory, as a local Dask cluster's workers are.
_ROUNDS = ("import resource, sys\n"
           "blocks, mib = int(sys.argv[1]), int(sys.argv[2])\n"
           "def faults(): return resource.getrusage(resource.RUSAGE_SELF).ru_minflt\n"
           "for _ in range(3):\n"
           "    before = faults(); held = [bytearray(mib << 20) for _ in range(blocks)]\n"
           "    del held; print(faults() - before)\n")


def _faults_in_child(setup: str, blocks: int, mib: int) -> tuple[list[str], list[int]]:
    """What ``setup`` (Python calling keep_freed_memory) printed, and the pages each round
    of :data:`_ROUNDS` faulted in, in a process it then started."""
    parent = (f"import os, subprocess, sys\n{setup}\n"
              f"subprocess.run([sys.executable, '-c', {_ROUNDS!r}, '{blocks}', '{mib}'], "
              "check=True)\n")
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("MALLOC_") and k != "GLIBC_TUNABLES"}
    out = subprocess.run([sys.executable, "-c", parent], env=env, capture_output=True,
                         text=True, check=True).stdout.split()
    return out[:-3], [int(n) for n in out[-3:]]


def test_user_tuned_malloc_sees_malloc_variables_and_tunables():
    assert not user_tuned_malloc({})
    assert not user_tuned_malloc({"MALLOC": "1", "PATH": "/bin",
                                  "GLIBC_TUNABLES": "glibc.rtld.nns=2"})
    assert user_tuned_malloc({"MALLOC_ARENA_MAX_": "2"})
    assert user_tuned_malloc({"GLIBC_TUNABLES": "glibc.malloc.trim_threshold=0"})
    assert user_tuned_malloc(malloc_environment())


@pytest.mark.skipif(sys.platform != "linux", reason="glibc's malloc")
def test_processes_started_afterwards_reuse_freed_blocks():
    """In a process started after keep_freed_memory (a local Dask worker), a 24 MB block
    (SIFT's largest level at 1536 px is 25 MB) and 96 MB in blocks of 8 MB freed together
    (a scale space: glibc by itself would keep 64 MiB of it) fault in no fresh pages when
    allocated again. A second call changes nothing and says so."""
    printed, faults = _faults_in_child(
        "from scene3D.memory import keep_freed_memory\n"
        "print(keep_freed_memory(), keep_freed_memory(), os.environ['MALLOC_TRIM_THRESHOLD_'])",
        1, 24)
    assert printed == ["True", "False", str(KEPT_BYTES)]
    assert faults[0] > 5000 and max(faults[1:]) < 100  # 6144 pages of 4 KiB, then reused
    _, faults = _faults_in_child(
        "from scene3D.memory import keep_freed_memory; keep_freed_memory()", 12, 8)
    assert faults[0] > 20000 and max(faults[1:]) < 100


def test_a_user_setting_is_kept():
    """With a malloc variable of the user's, keep_freed_memory changes nothing."""
    code = ("import os; from scene3D.memory import keep_freed_memory; "
            "print(keep_freed_memory(), os.environ.get('MALLOC_TRIM_THRESHOLD_'))")
    env = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_")}
    out = subprocess.run([sys.executable, "-c", code], env={**env, "MALLOC_ARENA_MAX_": "2"},
                         capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "None"]
