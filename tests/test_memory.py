"""glibc malloc settings that keep freed memory for reuse (scene3D.memory)."""

import pytest

from scene3D import memory
from scene3D.memory import (
    DASK_WORKER_TRIM_BYTES,
    malloc_environment,
    user_tuned_malloc,
    worker_environment,
)

from .helpers import ROUNDS, counts_page_faults, run_python


def test_user_tuned_malloc_sees_malloc_variables_and_tunables():
    assert not user_tuned_malloc({})
    assert not user_tuned_malloc({"MALLOC": "1", "PATH": "/bin",
                                  "GLIBC_TUNABLES": "glibc.rtld.nns=2"})
    assert user_tuned_malloc({"MALLOC_ARENA_MAX": "2"})  # glibc's name: no trailing '_'
    assert user_tuned_malloc({"GLIBC_TUNABLES": "glibc.malloc.trim_threshold=0"})
    assert user_tuned_malloc(malloc_environment())


@counts_page_faults
def test_freed_blocks_are_reused():
    """A 24 MB block (SIFT's largest level at 1536 px is 25 MB) and 96 MB in blocks of 8 MB
    freed together (a scale space; glibc by itself keeps 64 MiB of it) fault in no fresh
    pages when allocated again; without the setting they do."""
    keep = ROUNDS + "from scene3D.memory import keep_freed_memory\nprint(keep_freed_memory())\n"
    kept, *faults = run_python(keep + "rounds(1, 24); rounds(12, 8)")
    assert kept == "True"
    faults = [int(n) for n in faults]
    assert faults[0] > 5000 and max(faults[1:3]) < 100  # 6144 pages of 4 KiB, then reused
    assert faults[3] > 10000 and max(faults[4:]) < 100  # 72 of its 96 MB fresh
    glibc = [int(n) for n in run_python(ROUNDS + "rounds(12, 8)")]
    assert min(glibc[1:]) > 5000  # the heap beyond 64 MiB given back and faulted in again


def test_a_user_setting_is_kept():
    """With a malloc variable of the user's (glibc's real MALLOC_ARENA_MAX),
    keep_freed_memory changes nothing, and a local Dask cluster's workers get no setting."""
    out = run_python("from scene3D import memory\n"
                     "print(memory.keep_freed_memory(), "
                     "memory.worker_environment({}).get('MALLOC_TRIM_THRESHOLD_'))",
                     MALLOC_ARENA_MAX="2")
    assert out == ["False", "None"]


def test_worker_environment_keeps_the_users_dask_setting(monkeypatch):
    """The local workers keep freed memory only when this process does, and only in place
    of Dask's own trim threshold: a value configured by the user is theirs."""
    dask_default = {"MALLOC_TRIM_THRESHOLD_": DASK_WORKER_TRIM_BYTES, "OMP_NUM_THREADS": 1}
    monkeypatch.setattr(memory, "_kept", False)
    assert worker_environment(dask_default) == dask_default
    monkeypatch.setattr(memory, "_kept", True)
    assert worker_environment(dask_default) == {**dask_default, **malloc_environment()}
    assert worker_environment({}) == malloc_environment()
    users = {"MALLOC_TRIM_THRESHOLD_": "0"}
    assert worker_environment(users) == users


@counts_page_faults
def test_a_local_dask_clusters_workers_keep_freed_memory():
    """A local cluster started after keep_freed_memory (reconstruct-views --workers) gives
    its workers the setting: there too a freed 24 MB block is reused."""
    pytest.importorskip("distributed")
    code = (ROUNDS + "import io, contextlib\n"
            "from scene3D.memory import keep_freed_memory\n"
            "from scene3D.engines.dask_engine import DaskEngine\n"
            "def task():\n"
            "    out = io.StringIO()\n"
            "    with contextlib.redirect_stdout(out): rounds(1, 24)\n"
            "    return out.getvalue()\n"
            "if __name__ == '__main__':\n"
            "    keep_freed_memory()\n"
            "    with DaskEngine.local(1) as engine:\n"
            "        print(engine.client.submit(task, pure=False).result())\n")
    faults = [int(n) for n in run_python(code)]
    assert faults[0] > 5000 and max(faults[1:]) < 100
