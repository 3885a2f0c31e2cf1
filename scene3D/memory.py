"""glibc malloc settings for processes that extract the features of image after image.

By default glibc maps each block over 128 KiB afresh and unmaps it when it is freed,
raising that threshold by itself only after a larger block is freed, and gives freed heap
beyond 128 KiB back to the system (raised along, to at most 64 MiB). SIFT's scale space
(at the book's 768 px, images of 6 MB upscaled to 1536 x 1024, float32, about 90 MB; at
1536 px about 350 MB) is then mapped, touched page by page and given back at every
image, which costs every image its page faults again
(docs/benchmarks.md#freed-memory-kept-for-reuse). :func:`keep_freed_memory` keeps it; the
command-line scripts call it when they start, and a local Dask cluster they start gets it
for its workers (:func:`worker_environment`; docs/cli.md, memory). Linux (glibc) only;
elsewhere it does nothing. Importing this module changes nothing.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping

#: Blocks up to this size come from the heap and are reused: glibc's own ceiling for the
#: threshold it raises by itself (32 MiB on 64-bit systems, also the most ``mallopt``
#: takes); SIFT's largest level at 1536 px is 25 MB.
MMAP_THRESHOLD_BYTES = 32 << 20
#: Freed heap kept before it goes back to the system: more than one image's scale space at
#: 1536 px (about 350 MB), so that the next image reuses it; glibc's own ceiling of 64 MiB
#: is too little at 1536 px. A process's peak memory grows by up to this much, in practice
#: by a fifth to a quarter (docs/benchmarks.md#freed-memory-kept-for-reuse).
KEPT_BYTES = 512 << 20
#: glibc's ``mallopt`` parameters (malloc.h).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: The trim threshold a Dask nanny gives its workers unless configured otherwise
#: (``distributed.nanny.pre-spawn-environ``): freed memory back to the system at once.
DASK_WORKER_TRIM_BYTES = 65536
#: Whether :func:`keep_freed_memory` set this process's malloc.
_kept = False


def malloc_environment() -> dict[str, str]:
    """The environment variables that give a process started with them the settings of
    :func:`keep_freed_memory` (glibc reads them at start), e.g. for ``dask worker``."""
    return {"MALLOC_MMAP_THRESHOLD_": str(MMAP_THRESHOLD_BYTES),
            "MALLOC_TRIM_THRESHOLD_": str(KEPT_BYTES)}


def user_tuned_malloc(environ: Mapping[str, str]) -> bool:
    """Whether ``environ`` holds a malloc setting: a ``MALLOC_...`` variable (glibc's are
    ``MALLOC_ARENA_MAX``, ``MALLOC_TRIM_THRESHOLD_`` and the like), or ``glibc.malloc``
    in ``GLIBC_TUNABLES``.

    Parameters
    ----------
    environ : mapping of str to str
        An environment (``os.environ``).

    Returns
    -------
    bool
    """
    return (any(k.startswith("MALLOC_") for k in environ)
            or "glibc.malloc" in environ.get("GLIBC_TUNABLES", ""))


def worker_environment(spawn_environ: Mapping[str, object]) -> dict[str, object]:
    """The environment a local Dask cluster's nanny gives its workers
    (``distributed.nanny.pre-spawn-environ``, ``spawn_environ``), with
    :func:`malloc_environment` when this process keeps freed memory
    (:func:`keep_freed_memory`) and the configuration holds Dask's own trim threshold
    (:data:`DASK_WORKER_TRIM_BYTES`; another value is the user's, and kept). Each worker
    then holds up to :data:`KEPT_BYTES` for its next image.

    Parameters
    ----------
    spawn_environ : mapping of str to object
        Dask's ``distributed.nanny.pre-spawn-environ`` configuration.

    Returns
    -------
    dict[str, object]
    """
    environ = dict(spawn_environ)
    trim = environ.get("MALLOC_TRIM_THRESHOLD_", DASK_WORKER_TRIM_BYTES)
    if _kept and str(trim) == str(DASK_WORKER_TRIM_BYTES):
        environ.update(malloc_environment())
    return environ


def keep_freed_memory() -> bool:
    """Let glibc's malloc reuse large freed blocks instead of returning them to the system.

    Sets ``M_MMAP_THRESHOLD`` to :data:`MMAP_THRESHOLD_BYTES` and ``M_TRIM_THRESHOLD`` (the
    freed heap kept) to :data:`KEPT_BYTES` in this process (``mallopt``); a local Dask
    cluster started afterwards passes them on to its workers (:func:`worker_environment`).
    Call it before large allocations. Only on Linux, and only when the user has not tuned
    malloc (:func:`user_tuned_malloc`), whose settings are kept. Returns whether it set
    them.
    """
    global _kept
    if sys.platform != "linux" or user_tuned_malloc(os.environ):
        return False
    import ctypes

    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # no C library symbols, or not glibc's malloc
        return False
    _kept = bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)
                 and mallopt(_M_TRIM_THRESHOLD, KEPT_BYTES))
    return _kept
