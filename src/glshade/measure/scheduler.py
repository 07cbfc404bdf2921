"""Joining an existing Dask cluster (``--scheduler ADDRESS``) within a hard deadline.

Dask's own client waits without a limit for the first answer of whatever accepted its
TCP connection, so a silent listener or an HTTP server hangs it. Here the whole
connection (the TCP connection, Dask's handshake, the client's first exchange with the
scheduler, the worker plugin's registration) runs in a helper thread that the caller
waits for at most ``timeout_s`` (plus :data:`GRACE_S`), and every failure is one
:class:`~glshade.errors.GlshadeError` naming what was found at the address:

- a malformed address (no port, a port outside [1, 65535], an unknown scheme, an IPv6
  address without brackets): at once, nothing is contacted;
- a host that does not resolve: at once;
- nothing listening (connection refused, tried again until the deadline), or no answer:
  "no Dask scheduler answered within T s";
- something that accepted the connection but did not answer Dask's handshake, answered
  in another protocol, or is a Dask worker: "not a Dask scheduler".
"""

from __future__ import annotations

import asyncio
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from glshade.errors import GlshadeError, printable

if TYPE_CHECKING:
    from distributed import Client
    from distributed.diagnostics.plugin import WorkerPlugin

#: Schemes whose location is HOST:PORT (checked here, and reached over TCP first).
HOST_PORT_SCHEMES = ("tcp", "tls", "ws", "wss")
#: Dask's other built-in schemes, passed on to Dask as typed.
OTHER_SCHEMES = ("inproc", "ucx")
#: What a scheduler address looks like.
EXAMPLE = "tcp://HOST:PORT, e.g. tcp://head:8786"
#: Seconds past the deadline the caller waits for the helper thread to name what it found
#: (its own steps stop at the deadline).
GRACE_S = 0.5


@dataclass(frozen=True)
class SchedulerAddress:
    """A scheduler address as typed, and its parts (``host``/``port``: None for the
    schemes without them)."""

    text: str
    scheme: str
    host: str | None = None
    port: int | None = None

    @property
    def where(self) -> str:
        """The host and port, for messages (the address itself for other schemes)."""
        if self.host is None:
            return self.text
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{host}:{self.port}"

    def error(self, finding: str) -> GlshadeError:
        """``finding`` as the one-line error about this address (control characters
        shown escaped)."""
        return GlshadeError(printable(f"--scheduler {self.text or repr(self.text)}: {finding}"))


def parse_address(text: str) -> SchedulerAddress:
    """``text`` checked as a Dask scheduler address (no scheme means ``tcp``, as in Dask);
    a GlshadeError saying what is wrong with it otherwise."""
    bare = SchedulerAddress(text, "tcp")
    scheme, sep, location = text.rpartition("://")
    scheme = scheme if sep else "tcp"
    if scheme not in HOST_PORT_SCHEMES:
        if scheme in OTHER_SCHEMES or _dask_knows(scheme):
            return SchedulerAddress(text, scheme)
        raise bare.error(
            f"not a Dask scheduler address (unknown scheme {scheme!r}: Dask's are "
            f"{', '.join(sorted(HOST_PORT_SCHEMES + OTHER_SCHEMES))}); expected {EXAMPLE}"
        )
    try:
        host, port = _host_port(location)
    except ValueError as exc:
        raise bare.error(f"not a Dask scheduler address ({exc}); expected {EXAMPLE}") from None
    return SchedulerAddress(text, scheme, host, port)


def _host_port(location: str) -> tuple[str, int]:
    """HOST:PORT (an IPv6 host in brackets) split and checked."""
    if location.startswith("["):
        host, sep, tail = location[1:].partition("]")
        if not sep or (tail and not tail.startswith(":")):
            raise ValueError("an IPv6 host is written in brackets: [::1]:8786")
        port_text = tail[1:]
    else:
        host, sep, port_text = location.rpartition(":")
        if ":" in host:
            raise ValueError("an IPv6 host needs brackets: tcp://[::1]:8786")
        if not sep:
            host, port_text = location, ""
    if not host:
        raise ValueError("no host")
    if not port_text:
        raise ValueError("no port")
    port = int(port_text) if port_text.isdigit() and port_text.isascii() else -1
    if not 1 <= port <= 65535:
        raise ValueError(f"the port must be an integer in [1, 65535], got {port_text}")
    return host, port


def _dask_knows(scheme: str) -> bool:
    """Whether an installed package adds ``scheme`` to Dask (an entry point)."""
    from distributed.comm.registry import get_backend

    try:
        get_backend(scheme)
    except ValueError:
        return False
    return True


# ------------------------------------------------------------------ within a deadline
def within_deadline(
    timeout_s: float,
    work: Callable[[float], Any],
    late: Callable[[Any], None],
    expired: GlshadeError,
) -> Any:
    """``work(deadline)`` (a ``time.monotonic()`` instant) run in a daemon thread, its
    result or exception returned or raised here; after ``timeout_s + GRACE_S`` seconds,
    ``expired`` is raised, and the thread is left to finish alone: ``late(result)`` is
    called with what it makes after all (to close it)."""
    handoff = _Handoff()
    deadline = time.monotonic() + timeout_s

    def run() -> None:
        try:
            outcome: tuple[bool, Any] = (True, work(deadline))
        except BaseException as exc:  # handed to the caller, raised there
            outcome = (False, exc)
        if not handoff.give(outcome) and outcome[0]:
            late(outcome[1])

    threading.Thread(target=run, name="glshade-connect", daemon=True).start()
    outcome = handoff.take(timeout_s + GRACE_S)
    if outcome is None:
        raise expired
    ok, value = outcome
    if not ok:
        raise value
    return value


class _Handoff:
    """One outcome passed from a thread to a caller that may have stopped waiting."""

    def __init__(self) -> None:
        self._ready = threading.Condition()
        self._outcome: tuple[bool, Any] | None = None
        self._abandoned = False

    def give(self, outcome: tuple[bool, Any]) -> bool:
        """Hand ``outcome`` over; False when the caller has stopped waiting."""
        with self._ready:
            if self._abandoned:
                return False
            self._outcome = outcome
            self._ready.notify()
            return True

    def take(self, timeout_s: float) -> tuple[bool, Any] | None:
        """The outcome, or None (and the thread is told so) after ``timeout_s``."""
        with self._ready:
            self._ready.wait_for(lambda: self._outcome is not None, timeout_s)
            if self._outcome is None:
                self._abandoned = True
            return self._outcome


# ------------------------------------------------------------------ joining
def check_scheduler(text: str, timeout_s: float, verbose: bool = False) -> SchedulerAddress:
    """The address checked, and a Dask scheduler found there, within ``timeout_s``
    (:func:`probe`); nothing else is started. Dask's loggers are quietened first unless
    ``verbose`` (:func:`glshade.logs.quiet_libraries`)."""
    address = parse_address(text)
    import distributed  # noqa: F401  (its import sets its loggers' levels: quieten after it)

    from glshade.logs import quiet_libraries

    quiet_libraries(verbose)
    within_deadline(
        timeout_s,
        lambda deadline: probe(address, deadline, timeout_s),
        lambda _: None,
        address.error(f"no Dask scheduler answered within {timeout_s:g} s"),
    )
    return address


def join_scheduler(text: str, timeout_s: float, plugin: WorkerPlugin, plugin_name: str) -> Client:
    """A :class:`distributed.Client` of the scheduler at ``text`` with ``plugin``
    registered on its workers, all within ``timeout_s`` (plus :data:`GRACE_S`)."""
    address = parse_address(text)

    def work(deadline: float) -> Client:
        probe(address, deadline, timeout_s)
        return _client(address, deadline, timeout_s, plugin, plugin_name)

    return within_deadline(
        timeout_s,
        work,
        lambda client: client.close(),
        address.error(
            f"no Dask scheduler answered within {timeout_s:g} s (the connection to "
            f"{address.where} was not complete by then)"
        ),
    )


def _client(
    address: SchedulerAddress, deadline: float, timeout_s: float, plugin: WorkerPlugin, name: str
) -> Client:
    from distributed import Client

    left = max(deadline - time.monotonic(), 0.1)
    try:
        client = Client(address.text, timeout=f"{left}s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise address.error(
            f"no Dask scheduler answered within {timeout_s:g} s ({_first_line(exc)})"
        ) from None
    try:
        client.register_plugin(plugin, name=name)
    except BaseException:
        client.close()
        raise
    return client


def probe(address: SchedulerAddress, deadline: float, timeout_s: float) -> None:
    """A Dask scheduler answers at ``address`` by ``deadline``, or a GlshadeError naming
    what was found there: a TCP connection first (for HOST:PORT schemes), then Dask's
    handshake and the ``identity`` request (``timeout_s``: the time given, for messages)."""
    if address.host is not None:
        _reach(address, deadline, timeout_s)
    try:
        kind = asyncio.run(asyncio.wait_for(_identity(address.text, deadline), _left(deadline)))
    except TimeoutError:
        raise address.error(
            f"not a Dask scheduler: {address.where} accepted the connection but gave no Dask "
            f"answer within {timeout_s:g} s"
        ) from None
    except Exception as exc:  # anything a stranger's bytes make of Dask's reader
        if address.host is None:  # inproc, ucx: Dask's own words
            raise address.error(
                f"no Dask scheduler answered ({type(exc).__name__}: {_first_line(exc)[:120]})"
            ) from None
        raise address.error(
            f"not a Dask scheduler: {address.where} answered, but not in Dask's protocol "
            f"(Dask's reader raised {type(exc).__name__})"
        ) from None
    if kind != "Scheduler":
        raise address.error(f"not a Dask scheduler: a Dask {kind} answers at {address.where}")


async def _identity(text: str, deadline: float) -> str:
    """The ``type`` a Dask server at ``text`` says it is (``Scheduler``, ``Worker``)."""
    from distributed.comm import connect

    comm = await connect(text, timeout=_left(deadline))
    try:
        await comm.write({"op": "identity", "reply": True})
        answer = await comm.read()
    finally:
        comm.abort()
    return str(answer.get("type", "server of unknown type")) if isinstance(answer, dict) else "?"


def _reach(address: SchedulerAddress, deadline: float, timeout_s: float) -> None:
    """A TCP connection to the address's host and port by ``deadline`` (a refused one is
    tried again, as Dask does, for a scheduler that is starting), or a GlshadeError."""
    assert address.host is not None and address.port is not None
    try:
        socket.getaddrinfo(address.host, address.port, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError) as exc:
        why = exc.strerror if isinstance(exc, socket.gaierror) else "not a host name"
        raise address.error(f"the host {address.host!r} does not resolve ({why})") from None
    refused = False
    while (left := _left(deadline)) > 0:
        try:
            with socket.create_connection((address.host, address.port), timeout=left):
                return
        except ConnectionRefusedError:
            refused = True
            time.sleep(min(0.1, left))
        except TimeoutError:
            break
        except OSError as exc:
            raise address.error(
                f"no Dask scheduler answered ({address.where}: {exc.strerror or exc})"
            ) from None
    found = (
        f"nothing listens at {address.where}: connection refused"
        if refused
        else f"{address.where} did not accept the connection"
    )
    raise address.error(f"no Dask scheduler answered within {timeout_s:g} s ({found})")


def _left(deadline: float) -> float:
    return max(deadline - time.monotonic(), 0.0)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
