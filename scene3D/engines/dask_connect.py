"""The Dask engine's checks before it uses a cluster (:meth:`DaskEngine.connect
<scene3D.engines.dask_engine.DaskEngine.connect>`).

That a Dask scheduler, and not another server, listens at an address
(:func:`probe_scheduler`, :func:`server_type`), and that every worker runs the
client's scene3D (:func:`check_worker_versions`). Dask is imported only by the
functions that talk to it.
"""

from __future__ import annotations

import socket
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from ..errors import first_line
from .dask_worker import scene3d_version


def check_worker_versions(client: Any, address: str) -> None:
    """Raise ``OSError`` unless every worker runs the client's scene3D: the tasks are its
    functions, which a worker without it cannot even unpickle, and another version may
    compute something else.

    Parameters
    ----------
    client : distributed.Client
        A connected client.
    address : str
        The scheduler's address, for the message.

    Raises
    ------
    OSError
        A worker cannot run scene3D, or runs another version.
    """
    from .. import __version__

    try:
        versions = client.run(scene3d_version)
    except Exception as exc:  # the worker's ModuleNotFoundError, or what unpickling raised
        raise OSError(f"the workers of {address!r} cannot run scene3D ({first_line(exc)}): "
                      f"install scene3D {__version__}, the client's, where they run"
                      ) from None
    other = {w: v for w, v in versions.items() if v != __version__}
    if other:
        worker, version = next(iter(other.items()))
        raise OSError(f"worker {worker} runs scene3D {version} and this client {__version__}"
                      f"{f' ({len(other) - 1} more alike)' if len(other) > 1 else ''}: "
                      "install one version everywhere")


def probe_scheduler(address: str, host: str, port: int, timeout_s: float) -> None:
    """Raise ``OSError`` unless a Dask scheduler listens at ``host:port``: one sends its
    handshake (a frame whose 8-byte length header comes first) as soon as a connection
    opens. Another server (the dashboard's web server, say) sends nothing, or something
    else, and Dask's client would wait on it or misread it.

    Parameters
    ----------
    address : str
        The address as given, for the message.
    host : str
        Its host.
    port : int
        Its port.
    timeout_s : float
        Seconds to wait for the connection and the handshake.

    Raises
    ------
    OSError
        Nothing answers, or not as a Dask scheduler.
    """
    try:
        with socket.create_connection((host, port), timeout=timeout_s) as probe:
            header = probe.recv(8)
    except TimeoutError:
        header = b""
    except OSError as exc:
        raise OSError(f"cannot connect to the Dask scheduler at {address!r}: "
                      f"{exc.strerror or exc}") from None
    if len(header) < 8 or int.from_bytes(header, "little") > 1 << 20:
        raise OSError(f"what listens at {address!r} does not answer as a Dask scheduler (the "
                      "scheduler's port is 8786 by default, its dashboard's 8787)")


def server_type(address: str, timeout_s: float) -> str:
    """What kind of Dask server answers at ``address``: 'Scheduler', 'Worker', 'Nanny'
    (its ``identity``). Asked on a thread of its own, so that a caller inside an event
    loop (a notebook) can ask too.

    Parameters
    ----------
    address : str
        A Dask server's address.
    timeout_s : float
        Seconds to wait for its answer.

    Returns
    -------
    str
    """
    import asyncio

    from distributed.core import rpc

    async def identity() -> dict:
        async with rpc(address, timeout=timeout_s) as server:
            return await server.identity()

    with ThreadPoolExecutor(1) as thread:
        return str(thread.submit(asyncio.run, identity()).result().get("type", "unknown"))
