"""A sweep's ``--dask ADDRESS``: connect to a Dask scheduler up front, with a bounded wait and one clear line.

Without this check a closed port blocks for distributed's default connect
timeout and then ends in a traceback, and a scheduler without workers leaves
the sweep waiting forever. :func:`connect` checks the address, reaches the
scheduler within :data:`CONNECT_TIMEOUT` seconds and waits at most
:data:`WORKER_TIMEOUT` seconds for a first worker; otherwise it raises a
``ConfigError`` naming the address.
"""

from __future__ import annotations

import socket
from typing import Any

from nsbench.errors import ConfigError

#: Seconds allowed to reach the scheduler.
CONNECT_TIMEOUT = 10.0
#: Seconds allowed for the first worker to be there.
WORKER_TIMEOUT = 30.0


def _host_port(address: str) -> tuple[str, str, int | None]:
    """``(scheme, host, port)`` of a scheduler address; ``ConfigError`` if it is not one."""
    from distributed.comm import parse_address
    from distributed.comm.addressing import parse_host_port

    try:
        scheme, location = parse_address(address)
        if scheme not in ("tcp", "tls", "ws", "wss"):
            return scheme, location, None
        host, port = parse_host_port(location)
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"--dask {address!r} is not a scheduler address such as tcp://host:8786 ({exc})") from None
    if not host or not 0 < int(port) < 65536:
        raise ConfigError(f"--dask {address!r} is not a scheduler address such as tcp://host:8786")
    return scheme, host, int(port)


def _discard_half_built_client(exc: BaseException) -> None:
    """Stop the ``Client`` a failed constructor left behind, so that its ``__del__`` is quiet at exit."""
    from distributed import Client

    tb = exc.__traceback__
    while tb is not None:
        obj = tb.tb_frame.f_locals.get("self")
        if isinstance(obj, Client):
            try:
                obj.status = "closed"
                obj._loop_runner.stop()
            except Exception:  # noqa: BLE001 - best effort, the error itself is reported
                pass
            return
        tb = tb.tb_next


def connect(address: str, *, connect_timeout: float | None = None, worker_timeout: float | None = None) -> Any:
    """A ``distributed.Client`` on the scheduler at ``address``, with at least one worker.

    Parameters
    ----------
    address
        Scheduler address, e.g. ``tcp://host:8786``.
    connect_timeout
        Seconds allowed to reach the scheduler (default :data:`CONNECT_TIMEOUT`).
    worker_timeout
        Seconds allowed for a first worker (default :data:`WORKER_TIMEOUT`).

    Returns
    -------
    distributed.Client
        Connected; the caller closes it.

    Raises
    ------
    ConfigError
        A malformed address, a host that does not resolve, a closed port, a
        peer that is not a Dask scheduler, or a scheduler without workers; the
        message names the address.
    """
    connect_timeout = CONNECT_TIMEOUT if connect_timeout is None else connect_timeout
    worker_timeout = WORKER_TIMEOUT if worker_timeout is None else worker_timeout
    try:
        from distributed import Client
    except ImportError:  # pragma: no cover - distributed is a dependency
        raise ConfigError("--dask needs the 'distributed' package (pip install 'dask[distributed]')") from None
    scheme, host, port = _host_port(address)
    if port is not None:  # a closed port or an unknown host: fail fast, before a Client exists
        try:
            with socket.create_connection((host, port), timeout=connect_timeout) as sock:
                if scheme == "tcp":
                    # a Dask scheduler sends its handshake at once; another server (HTTP, ssh...)
                    # waits for us, and distributed's Client would then wait forever
                    sock.settimeout(connect_timeout)
                    try:
                        greeting = sock.recv(1)
                    except (TimeoutError, socket.timeout):
                        greeting = b""
                    if not greeting:
                        raise ConfigError(
                            f"--dask {address}: the server there does not answer like a Dask "
                            f"scheduler (no handshake within {connect_timeout:g} s)"
                        )
        except socket.gaierror as exc:
            raise ConfigError(f"--dask {address}: host {host!r} not found ({exc.strerror})") from None
        except (TimeoutError, socket.timeout):
            raise ConfigError(
                f"--dask {address}: no answer within {connect_timeout:g} s "
                "(is the scheduler running, and the port open?)"
            ) from None
        except OSError as exc:
            raise ConfigError(
                f"--dask {address}: cannot connect ({exc.strerror or exc}); is the scheduler running?"
            ) from None
    try:
        client = Client(address, timeout=connect_timeout, set_as_default=False)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        _discard_half_built_client(exc)
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise ConfigError(
            f"--dask {address}: cannot connect to a Dask scheduler within {connect_timeout:g} s ({reason})"
        ) from None
    try:
        client.wait_for_workers(1, timeout=worker_timeout)
    except (OSError, TimeoutError) as exc:
        client.close()
        if isinstance(exc, TimeoutError):
            raise ConfigError(
                f"--dask {address}: the scheduler has no workers (none joined within "
                f"{worker_timeout:g} s); start one with 'dask worker {address}'"
            ) from None
        raise ConfigError(
            f"--dask {address}: lost the scheduler while waiting for workers ({exc.strerror or exc})"
        ) from None
    return client
