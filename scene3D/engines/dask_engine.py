"""The Dask engine: independent tasks on the workers of a ``dask.distributed`` cluster.

:class:`DaskEngine` implements :class:`scene3D.engines.Engine` with a
``distributed.Client``: :meth:`~DaskEngine.map` submits one task per argument
tuple, reports progress as tasks finish and yields the results in the order of
the arguments; :meth:`~DaskEngine.share` leaves a value on the cluster for later
tasks. Dask (the optional extra ``distributed``) is imported when an engine is
built, never when this module is imported, and the geometry never imports it. What runs on
the workers is :mod:`scene3D.engines.dask_worker`; the checks of an address and of the
workers' scene3D, :mod:`scene3D.engines.dask_connect`.

Workers
    Every worker needs scene3D installed (tasks name module-level functions of
    scene3D, which the workers import). A task runs on one core: the engine sets
    ``cv2.setNumThreads(1)`` on the workers, and the Dask nanny starts workers
    with one BLAS thread, so start one single-threaded worker process per core
    (``dask worker ADDRESS --nworkers N --nthreads 1``; :meth:`DaskEngine.local`
    does the same on this machine).

Files
    A task argument that is a :class:`pathlib.Path` is a file the task reads.
    The engine makes it absolute (a worker's working folder is not the
    client's) and, before the first task that names it, asks every worker for
    the file's size (``files="auto"``, the default). Workers that all see it
    with the client's size (a shared filesystem, or one machine) get the path;
    otherwise the client reads the file and sends its bytes with the task, and
    the worker hands the task a temporary copy under the same name. A file
    that the client cannot read either is left to the workers (it may exist on
    the cluster only). ``files="shared"`` always sends paths, ``files="send"``
    always bytes. A file a worker cannot read raises the task's ``OSError``
    naming the file and the worker.

Failures
    A worker that dies (killed, out of memory, its machine gone) takes its
    running tasks and the results it held with it. The scheduler runs those
    tasks again on the other workers, and recomputes lost results that later
    tasks still need: :meth:`~DaskEngine.share` hands on the task that made a
    :meth:`~DaskEngine.map` result, and sends any other value as a task that
    returns it (the scheduler keeps it), never as scattered data, which would be
    lost with its last worker. A task that
    was running on ``distributed.scheduler.allowed-failures`` + 1 dying workers
    (3 + 1 by default) is given up (:class:`scene3D.errors.EngineError`). An
    exception raised by the task itself is not retried: the tasks are
    deterministic, a second run would raise it again.
"""

from __future__ import annotations

import logging
import time
import uuid
import weakref
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import CancelledError
from pathlib import Path, PurePath
from typing import Any, Literal, TypeVar

from ..errors import EngineError, first_line, plural
from ..memory import worker_environment
from . import Progress
from .dask_connect import check_worker_versions, probe_scheduler, server_type
from .dask_worker import FileBytes, file_sizes, finished_tasks, run_task, shared_value

logger = logging.getLogger(__name__)

R = TypeVar("R")

FileMode = Literal["auto", "shared", "send"]

#: How long a run waits for a worker, in seconds: :meth:`DaskEngine.connect` for a first
#: one, and tasks on a cluster left without any (all died or left) before the run stops
#: with an :class:`~scene3D.errors.EngineError`.
NO_WORKER_TIMEOUT_S = 30.0

#: How to get the extra, quoted by every error about a missing Dask.
INSTALL_HINT = "pip install 'scene3D[distributed]' (dask.distributed)"


class MissingExtraError(ImportError):
    """``dask.distributed`` is not installed (the optional extra ``distributed``)."""


def require_distributed() -> Any:
    """The ``distributed`` module, or :class:`MissingExtraError` saying how to install it."""
    try:
        import distributed
    except ImportError:
        raise MissingExtraError(f"Dask is not installed: {INSTALL_HINT}") from None
    return distributed



class DaskEngine:
    """Tasks on the workers of a Dask cluster (see the module docstring).

    Parameters
    ----------
    client : distributed.Client
        A connected client. Build one with :meth:`connect` (a scheduler's address)
        or :meth:`local` (worker processes on this machine), or pass your own.
    files : {"auto", "shared", "send"}
        How :class:`pathlib.Path` arguments reach the workers: checked per file,
        always as paths, or always as bytes.
    opencv_threads : int or None
        ``cv2.setNumThreads`` on the workers (default 1: a task is one core's
        work); None leaves OpenCV's setting alone.
    owns : bool
        Close the client (and its local cluster) on :meth:`close`.
    name : str, optional
        How the engine is described (default: "dask" and the scheduler's address).

    Examples
    --------
    >>> from scene3D.io.images import read_image_size
    >>> with DaskEngine.connect("tcp://10.0.0.5:8786") as engine:   # doctest: +SKIP
    ...     sizes = list(engine.map(read_image_size, [(p,) for p in paths], label="sizes"))
    """

    def __init__(self, client: Any, *, files: FileMode = "auto", opencv_threads: int | None = 1,
                 owns: bool = False, name: str | None = None,
                 no_worker_timeout_s: float = NO_WORKER_TIMEOUT_S) -> None:
        if files not in ("auto", "shared", "send"):
            raise ValueError(f"`files` must be 'auto', 'shared' or 'send', got {files!r}")
        self._client = client
        self._files: FileMode = files
        self._opencv_threads = opencv_threads
        self._owns = owns
        self.name = name or f"dask {client.scheduler.address}"
        self._sent: dict[str, bool] = {}  # absolute path -> send bytes (True) or the path
        self._origins: dict[int, tuple[weakref.ref, Any]] = {}  # id(result) -> its future
        self._id = uuid.uuid4().hex
        self._no_worker_timeout_s = no_worker_timeout_s
        self.submitted: Counter[str] = Counter()  # tasks submitted, by label

    # -- building and closing -----------------------------------------------------------

    @classmethod
    def connect(cls, address: str, *, timeout_s: float = 10.0,
                wait_for_workers_s: float = NO_WORKER_TIMEOUT_S,
                **options: Any) -> DaskEngine:
        """Connect to a running scheduler (``dask scheduler``) at ``address``.

        Waits up to ``wait_for_workers_s`` for a first worker, then checks that the
        workers run the client's scene3D.

        Parameters
        ----------
        address : str
            The scheduler's address (``tcp://host:port``).
        timeout_s : float, default 10.0
            Seconds to wait for the scheduler.
        wait_for_workers_s : float, default NO_WORKER_TIMEOUT_S
            Seconds to wait for a first worker.
        **options
            Passed to :class:`DaskEngine` (``files``, ``opencv_threads``, ``name``, ...).

        Returns
        -------
        DaskEngine


        Raises
        ------
        MissingExtraError
            Dask is not installed.
        ValueError
            ``address`` is not an address.
        OSError
            Nothing answers at ``address`` within ``timeout_s``, no worker joined in
            time, or a worker runs another scene3D (or none).
        """
        distributed = require_distributed()
        try:
            scheme, _ = distributed.comm.parse_address(address)
            host, port = distributed.comm.get_address_host_port(address)
        except ValueError as exc:
            raise ValueError(f"bad Dask scheduler address {address!r} ({exc}); expected "
                             "such as tcp://10.0.0.5:8786") from None
        if not 0 < int(port or 0) < 65536:
            raise ValueError(f"bad Dask scheduler address {address!r} (port {port} is not "
                             "between 1 and 65535); expected such as tcp://10.0.0.5:8786")
        if scheme == "tcp":  # a quick look first: nothing listening is said at once
            probe_scheduler(address, host, port, timeout_s)
            kind = server_type(address, timeout_s)
            if kind != "Scheduler":  # Dask's client would fail with a traceback
                raise OSError(f"{address!r} is a Dask {kind.lower()}, not the scheduler: give "
                              "the address 'dask scheduler' prints (port 8786 by default)")
        if scheme == "tls" and distributed.Security().get_connection_args(
                "client").get("ssl_context") is None:
            raise ValueError(f"{address!r} needs TLS, and Dask's configuration holds no "
                             "certificates for it (distributed.comm.tls: ca-file, and client "
                             "cert and key)")
        try:
            client = distributed.Client(address, timeout=f"{timeout_s}s",
                                        set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise OSError(f"cannot connect to the Dask scheduler at {address!r}: "
                          f"{first_line(exc)}") from None
        try:
            client.wait_for_workers(1, timeout=wait_for_workers_s)
        except (OSError, TimeoutError):
            client.close()
            raise OSError(f"no worker joined the Dask scheduler at {address!r} within "
                          f"{wait_for_workers_s:g} s (start one with 'dask worker {address}')"
                          ) from None
        try:
            check_worker_versions(client, address)
        except OSError:
            client.close()
            raise
        engine = cls(client, owns=True, **options)
        logger.debug("connected to %s", engine.describe())
        return engine

    @classmethod
    def local(cls, workers: int, *, threads_per_worker: int = 1, **options: Any) -> DaskEngine:
        """Start ``workers`` worker processes on this machine (a ``distributed.LocalCluster``
        on 127.0.0.1; its web server on a free port, the workers' profiler off) and use
        them.

        Parameters
        ----------
        workers : int
            Number of worker processes (>= 1).
        threads_per_worker : int, default 1
            Threads per worker.
        **options
            Passed to :class:`DaskEngine`.

        Returns
        -------
        DaskEngine

        Raises
        ------
        ValueError
            If ``workers`` is below 1.
        MissingExtraError
            Dask is not installed.
        """
        if workers < 1:
            raise ValueError(f"`workers` must be at least 1, got {workers}")
        distributed = require_distributed()
        import dask

        # Without a dashboard to show them, the workers' statistical profiles (a stack
        # sample every 10 ms) are CPU spent for nothing: about 0.01 core per worker here.
        # The workers' own log is silenced below CRITICAL: a task that fails raises its
        # error here, where the command says it in one line; the worker's "Compute Failed"
        # and its traceback would say it again.
        # The workers keep freed memory for their next image when this process does
        # (scene3D.memory.worker_environment).
        spawn_environ = worker_environment(dask.config.get("distributed.nanny.pre-spawn-environ"))
        with dask.config.set({"distributed.worker.profile.enabled": False,
                              "distributed.nanny.pre-spawn-environ": spawn_environ}):
            cluster = distributed.LocalCluster(
                n_workers=workers, threads_per_worker=threads_per_worker, processes=True,
                host="127.0.0.1", dashboard_address=":0", silence_logs=logging.CRITICAL)
        try:
            client = distributed.Client(cluster, set_as_default=False)
        except BaseException:
            cluster.close()
            raise
        engine = cls(client, owns=True,
                     name=f"dask local ({workers} worker process{'es' * (workers > 1)})",
                     **options)
        logger.debug("started %s", engine.describe())
        return engine

    def close(self) -> None:
        """Forget shared values; close the client and its cluster if this engine made them."""
        self._origins.clear()
        if self._owns:
            cluster = self._client.cluster
            self._client.close()
            if cluster is not None:
                cluster.close()

    def __enter__(self) -> DaskEngine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def client(self) -> Any:
        """The ``distributed.Client``."""
        return self._client

    def workers(self) -> dict[str, int]:
        """The workers now connected: ``{address: threads}``."""
        return dict(self._client.nthreads())

    def describe(self) -> str:
        """The engine's name with its workers and threads."""
        workers = self.workers()
        return (f"{self.name}: {plural(len(workers), 'worker')}, "
                f"{plural(sum(workers.values()), 'thread')}")

    def task_counts(self) -> dict[str, dict[str, int]]:
        """Tasks of this engine finished by each connected worker process, by label:
        ``{worker address: {label: count}}`` (a worker that died took its counts along)."""
        return self._client.run(finished_tasks, self._id)

    # -- the Engine interface -----------------------------------------------------------

    def map(self, fn: Callable[..., R], arguments: Iterable[tuple], *, label: str = "tasks",
            progress: Progress | None = None) -> Iterator[R]:
        """Submit ``fn(*a)`` for every tuple ``a`` now; yield the results in order.

        ``progress(label, done, total)`` is called on this thread as tasks finish, in
        any order. A task's exception is raised when its turn comes; the tasks not
        yet yielded are then cancelled.

        Parameters
        ----------
        fn : callable
            A module-level function without side effects.
        arguments : iterable of tuple
            The arguments of each task.
        label : str, default "tasks"
            Names the tasks in progress reports.
        progress : callable or None, default None
            ``progress(label, done, total)``; None for no reports.

        Yields
        ------
        object
            Each task's result, in the order of ``arguments``.
        """
        calls = [self._prepare(tuple(args)) for args in arguments]
        token = uuid.uuid4().hex[:12]
        tag = f"{self._id}/{label}"
        futures = [self._client.submit(run_task, fn, tag, self._opencv_threads, *args,
                                       key=f"{label}-{token}-{i}", pure=False)
                   for i, args in enumerate(calls)]
        del calls
        self.submitted[label] += len(futures)
        return self._results(futures, label, progress)

    def share(self, value: Any) -> Any:
        """A handle to ``value`` on the cluster, for later tasks' arguments.

        A result of :meth:`map` is handed on as the task that made it (nothing is
        sent, and a worker's death only means that the task runs again). Any other
        value (a map result's part, or one built on the client) is sent once, as a
        task that returns it: the scheduler keeps it, so that it too can be made
        again after a worker's death. Shared values are taken as immutable.

        Parameters
        ----------
        value : Any
            A value taken as immutable.

        Returns
        -------
        Any
            A future for it.
        """
        origin = self._origins.get(id(value))
        if origin is not None and origin[0]() is value:
            return origin[1]
        # A task that returns the value, rather than scatter(): the scheduler keeps the
        # task and runs it again if the worker holding the value dies, where scattered
        # data would be lost with its last worker.
        return self._client.submit(shared_value, value, key=f"shared-{uuid.uuid4().hex}",
                                   pure=False)

    # -- internals ----------------------------------------------------------------------

    def _results(self, futures: list[Any], label: str, progress: Progress | None
                 ) -> Iterator[Any]:
        distributed = require_distributed()
        total = len(futures)
        position = {future.key: i for i, future in enumerate(futures)}
        finished = [False] * total
        done = upcoming = 0
        try:
            for future in self._completed(distributed.as_completed(futures,
                                                                   loop=self._client.loop),
                                          label):
                finished[position[future.key]] = True
                done += 1
                if progress is not None:
                    progress(label, done, total)
                while upcoming < total and finished[upcoming]:
                    value = self._result(futures[upcoming], label, upcoming)
                    self._remember(value, futures[upcoming])
                    futures[upcoming] = None
                    upcoming += 1
                    yield value
        finally:
            left = [f for f in futures if f is not None and not f.done()]
            if left and self._client.status == "running":
                self._client.cancel(left)

    def _completed(self, pending: Any, label: str) -> Iterator[Any]:
        """The futures of ``pending`` (a ``distributed.as_completed``) as they finish.

        Dask reschedules the tasks of a worker that dies and waits for another one,
        without limit; a run whose workers have all gone would wait in silence. So
        while nothing finishes, the workers are counted once a second, and an
        :class:`EngineError` ends the wait when there has been none for
        ``no_worker_timeout_s``, or when the scheduler stops answering.
        """
        without_workers_since: float | None = None
        next_look = time.monotonic()
        while not pending.is_empty():
            finished = pending.next_batch(block=False)
            if finished:
                yield from finished
                continue
            now = time.monotonic()
            if now >= next_look:
                next_look = now + 1.0
                try:
                    has_workers = bool(self._client.nthreads())
                except Exception as exc:  # the scheduler is gone: any comm error
                    raise EngineError(f"lost the Dask scheduler while {label} tasks ran: "
                                      f"{first_line(exc)}", "scheduler_lost") from None
                if has_workers:
                    without_workers_since = None
                elif without_workers_since is None:
                    without_workers_since = now
                elif now - without_workers_since >= self._no_worker_timeout_s:
                    raise EngineError(
                        f"the Dask cluster has had no worker for "
                        f"{self._no_worker_timeout_s:g} s while {label} tasks waited (its "
                        "workers died or left); start one with 'dask worker ADDRESS'",
                        "no_workers")
            time.sleep(0.02)

    def _result(self, future: Any, label: str, index: int) -> Any:
        """``future``'s value. A finished task's value lives on the worker that made it:
        when that worker leaves before the value is fetched, Dask computes it again and
        the fetch waits for a worker, so it waits as :meth:`_completed` does, within the
        no-worker limit."""
        distributed = require_distributed()
        try:
            while True:
                for _ in self._completed(distributed.as_completed([future],
                                                                 loop=self._client.loop),
                                         label):
                    pass
                try:
                    return future.result(timeout=1.0)
                except TimeoutError:  # lost with its worker since it finished
                    continue
        except distributed.KilledWorker as exc:
            deaths = exc.allowed_failures + 1
            raise EngineError(f"{label} task {index} was given up: the worker running it died "
                              f"{plural(deaths, 'time')} (the last: "
                              f"{exc.last_worker.address})", "task_given_up") from None
        except CancelledError as exc:  # distributed's FutureCancelledError and older ones
            raise EngineError(f"{label} task {index} was cancelled: {exc}",
                              "task_cancelled") from None

    def _remember(self, value: Any, future: Any) -> None:
        """Keep ``future`` as the handle of ``value`` while the caller keeps ``value``."""
        try:
            ref = weakref.ref(value)
        except TypeError:  # e.g. a tuple: shared by scattering it
            return
        key = id(value)
        self._origins[key] = (ref, future)
        weakref.finalize(value, self._origins.pop, key, None)

    def _prepare(self, args: tuple) -> tuple:
        """Path arguments as absolute paths, or as bytes for workers that cannot read them."""
        paths = [str(Path(a).absolute()) for a in args if isinstance(a, PurePath)]
        unknown = [p for p in dict.fromkeys(paths) if p not in self._sent]
        if unknown:
            self._decide(unknown)
        prepared = []
        for arg in args:
            if isinstance(arg, PurePath):
                path = str(Path(arg).absolute())
                arg = FileBytes(path, Path(path).read_bytes()) if self._sent[path] \
                    else Path(path)
            prepared.append(arg)
        return tuple(prepared)

    def _decide(self, paths: list[str]) -> None:
        """Whether each file goes to the workers as its path or as its bytes."""
        if self._files != "auto":
            self._sent.update(dict.fromkeys(paths, self._files == "send"))
            return
        here = file_sizes(paths)
        there = self._client.run(file_sizes, paths)
        for k, path in enumerate(paths):
            blind = sorted(w for w, sizes in there.items() if sizes[k] != here[k])
            self._sent[path] = here[k] is not None and bool(blind)
            if self._sent[path]:
                logger.info("'%s': sent to the workers as bytes (%s cannot read it as "
                            "this machine does)", path, ", ".join(blind))
