"""Hostile input to the Dask side: ``--scheduler`` addresses that are malformed, reach
nothing, or reach something that is not a Dask scheduler; ``--workers`` and ``--threads``
beyond this machine's cores and memory budget; Dask's own log output.

Oracles: the CLI's contract (exit code 2, exactly one stderr line ``glshade: error: ...``
naming the value typed and what was found or allowed, no output directory written), the
listeners' own behaviour (a socket server that never speaks, Python's HTTP server, one
that sends a banner), and the log output of real worker processes compared with a line
they print themselves.
"""

from __future__ import annotations

import http.server
import logging
import os
import socket
import socketserver
import subprocess
import sys
import textwrap
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from glshade.app.cli import main
from glshade.app.commands.paper import paper_workers
from glshade.errors import GlshadeError
from glshade.logs import QUIET_LEVELS, quiet_libraries
from glshade.measure import capacity
from glshade.measure.executors import Distribution
from glshade.measure.scheduler import check_scheduler, parse_address, within_deadline
from glshade.study.plan import StudyPlan

SWEEP = 'size = 32\n[grid]\n"camera.theta_deg" = [45]\n'


def _glshade(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """The real command line in a subprocess (its stderr is all the user would see)."""
    return subprocess.run(
        [sys.executable, "-m", "glshade", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,  # a hang fails the test instead of the suite
    )


def _assert_one_error_line(code: int, err: str, *fragments: str) -> None:
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("glshade: error: "), err
    for fragment in fragments:
        assert fragment in err, err


# --------------------------------------------------------------------------- listeners
class _Silent(socketserver.BaseRequestHandler):
    def handle(self) -> None:  # accept, never speak, hold the connection until it closes
        while self.request.recv(1 << 16):
            pass


class _Banner(socketserver.BaseRequestHandler):
    def handle(self) -> None:  # speak first, in another protocol (as SSH does)
        self.request.sendall(b"SSH-2.0-OpenSSH_9.6\r\n")
        while self.request.recv(1 << 16):
            pass


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:
        pass


@pytest.fixture
def listener(request) -> Iterator[str]:
    """``tcp://127.0.0.1:PORT`` of a server thread of the kind the test names."""
    server: socketserver.TCPServer
    if request.param == "http":
        server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Quiet)
    else:
        handler = {"silent": _Silent, "banner": _Banner}[request.param]
        server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), handler)
    server.daemon_threads = True
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        yield f"tcp://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


def _closed_port() -> int:
    """A port nothing listens on (bound, then released)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


# --------------------------------------------------------------------------- --scheduler
@pytest.mark.parametrize(
    ("address", "fragment"),
    [
        ("", "--scheduler '': not a Dask scheduler address (no host)"),
        ("tcp://", "(no host)"),
        ("tcp://host:notaport", "the port must be an integer in [1, 65535], got notaport"),
        ("tcp://host:99999", "the port must be an integer in [1, 65535], got 99999"),
        ("tcp://host:0", "got 0"),
        ("tcp://host", "(no port)"),
        ("foo://x", "unknown scheme 'foo'"),
        ("unix:///nonexistent/sock", "unknown scheme 'unix'"),
        ("/nonexistent/sock", "(no port)"),
        ("::::", "an IPv6 host needs brackets"),
        ("tcp://[::1", "an IPv6 host is written in brackets"),
    ],
)
def test_a_malformed_scheduler_address_is_refused_before_anything(address, fragment):
    with pytest.raises(GlshadeError) as caught:
        parse_address(address)
    assert fragment in str(caught.value) and "expected tcp://HOST:PORT" in str(caught.value)
    assert "\n" not in str(caught.value)


def test_well_formed_addresses_are_parsed_as_dask_reads_them():
    assert parse_address("tcp://head:8786").where == "head:8786"
    assert parse_address("head:8786").scheme == "tcp"  # Dask's default scheme
    assert parse_address("tls://[::1]:8786").where == "[::1]:8786"
    assert parse_address("inproc://10.0.0.1/1/1").host is None  # passed to Dask as typed


def test_bad_addresses_are_one_line_from_the_command_line(tmp_path, capfd):
    (tmp_path / "s.toml").write_text(SWEEP)
    closed = f"tcp://127.0.0.1:{_closed_port()}"
    for address, fragment in [
        ("tcp://host:notaport", "got notaport"),
        ("tcp://no-such-host.invalid:8786", "no-such-host.invalid"),
        (closed, f"no Dask scheduler answered within 1 s (nothing listens at {closed[6:]}"),
    ]:
        args = ["--scheduler", address, "--connect-timeout", "1", "--no-progress"]
        code = main(["sweep", str(tmp_path / "s.toml"), "--out", str(tmp_path / "o"), *args])
        _assert_one_error_line(code, capfd.readouterr().err, f"--scheduler {address}", fragment)
        assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("listener", "command"), [("silent", "sweep"), ("http", "optimize")], indirect=["listener"]
)
def test_a_listener_that_is_not_dask_is_named_within_the_timeout(listener, command, tmp_path):
    (tmp_path / "s.toml").write_text(SWEEP)
    what = ["s.toml", "--out", "o"] if command == "sweep" else ["--over", "camera.theta_deg=10..80"]
    run = _glshade(command, *what, "--scheduler", listener, "--connect-timeout", "1", cwd=tmp_path)
    where = listener.removeprefix("tcp://")
    _assert_one_error_line(
        run.returncode, run.stderr, f"--scheduler {listener}: not a Dask scheduler: {where} "
    )
    silent = f"{where} accepted the connection but gave no Dask answer within 1 s"
    # an HTTP server waits for a line break: it answers "HTTP/1.0 400" only if Dask's
    # handshake happens to hold the byte 0x0a (its lengths depend on the Python and Dask)
    http = f"{where} answered, but not in Dask's protocol"
    assert silent in run.stderr or (command == "optimize" and http in run.stderr), run.stderr
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("listener", ["banner"], indirect=True)
def test_a_listener_speaking_another_protocol_is_not_a_dask_scheduler(listener):
    with pytest.raises(GlshadeError, match="answered, but not in Dask's protocol"):
        check_scheduler(listener, 5)


def test_a_step_past_the_deadline_is_abandoned_and_what_it_makes_late_is_closed():
    release, closed = threading.Event(), []
    late_done = threading.Event()

    def hung(deadline: float) -> str:
        release.wait()
        return "client"

    def close(made) -> None:
        closed.append(made)
        late_done.set()

    with pytest.raises(GlshadeError, match="expired"):
        within_deadline(0.01, hung, close, GlshadeError("expired"))
    release.set()
    assert late_done.wait(30) and closed == ["client"]
    assert within_deadline(5, lambda deadline: deadline > 0, close, GlshadeError("x")) is True
    with pytest.raises(GlshadeError, match="raised"):
        within_deadline(5, _raises, close, GlshadeError("x"))


def _raises(deadline: float) -> None:
    raise GlshadeError("raised in the thread")


# --------------------------------------------------------------------------- --workers
@pytest.fixture
def two_cores(monkeypatch) -> None:
    monkeypatch.setattr(capacity, "usable_cores", lambda: 2)
    monkeypatch.delenv("GLSHADE_MEMORY_BUDGET_MB", raising=False)


def test_workers_are_bounded_by_the_cores_and_the_memory_budget(two_cores, monkeypatch):
    assert Distribution(workers=4).workers == 4
    with pytest.raises(GlshadeError) as caught:
        Distribution(workers=5)
    assert str(caught.value).startswith("--workers: must be an integer in [1, 4] on this machine")
    assert "2 CPU cores x 2 = 4" in str(caught.value) and str(caught.value).endswith("got 5")
    monkeypatch.setenv("GLSHADE_MEMORY_BUDGET_MB", "1000")
    capacity.check_worker_count(2, 1024 * 1024, "paper")  # 2 x 400 MiB
    with pytest.raises(GlshadeError, match=r"in \[1, 2\].*1000 MiB.*400 MiB per worker.*got 3"):
        capacity.check_worker_count(3, 1024 * 1024, "paper")
    with pytest.raises(GlshadeError, match="--workers 1: no worker process fits"):
        capacity.check_worker_count(1, 1024 * 1024, "pmd")  # 1408 MiB
    with pytest.raises(GlshadeError, match=r"--threads: must be an integer in \[1, 4\]"):
        Distribution(threads=5)


def test_the_paper_study_bounds_its_workers_and_auto_fits_them(two_cores, monkeypatch):
    large = StudyPlan(size=1024)
    assert paper_workers("auto", large, None) == 2
    assert paper_workers("4", StudyPlan(size=256), None) == 4
    with pytest.raises(GlshadeError, match=r"auto or an integer in \[0, 4\].*got 5"):
        paper_workers("5", large, None)
    monkeypatch.setenv("GLSHADE_MEMORY_BUDGET_MB", "500")  # one worker of 400 MiB
    assert paper_workers("auto", large, None) == 0  # one worker does not repay its start


def test_too_many_workers_is_one_line_from_the_command_line(tmp_path, capfd):
    (tmp_path / "s.toml").write_text(SWEEP)
    most = capacity.worker_limit().allowed  # before the frames' size is known
    most_paper = capacity.worker_limit(1024 * 1024, "paper").allowed  # the study's 1024²
    for args, allowed in (
        (["sweep", "s.toml", "--out", "o", "--workers", "256"], f"[1, {most}]"),
        (["optimize", "--over", "camera.theta_deg=10..80", "--workers", str(most + 1)], "[1, "),
        (["paper", "--out", "o", "--workers", "256"], f"auto or an integer in [0, {most_paper}]"),
    ):
        code = main([str(tmp_path / arg) if arg in ("s.toml", "o") else arg for arg in args])
        err = capfd.readouterr().err
        _assert_one_error_line(code, err, "--workers: must be ", allowed, "on this machine")
        assert err.rstrip().endswith(f"got {args[-1]}")
    assert not (tmp_path / "o").exists()


# --------------------------------------------------------------------------- log output
@pytest.fixture
def saved_levels() -> Iterator[None]:
    names = [
        name
        for name in logging.root.manager.loggerDict
        if any(name == root or name.startswith(root + ".") for root in QUIET_LEVELS)
    ]
    levels = {name: logging.getLogger(name).level for name in [*names, *QUIET_LEVELS]}
    yield
    for name, level in levels.items():
        logging.getLogger(name).setLevel(level)


def test_quiet_libraries_silences_dask_unless_verbose(saved_levels):
    import distributed  # noqa: F401  (sets its loggers' levels, as on import in the CLI)

    for name in QUIET_LEVELS:
        logging.getLogger(name).setLevel(logging.NOTSET)
    logging.getLogger("distributed.client").setLevel(logging.WARNING)  # as Dask's import does
    logging.getLogger("fsspec").setLevel(logging.CRITICAL)  # a caller's own choice
    quiet_libraries(verbose=True)
    assert logging.getLogger("distributed.client").isEnabledFor(logging.ERROR)
    for _ in range(2):  # idempotent
        quiet_libraries()
        for name in ("distributed", "distributed.client", "distributed.worker", "asyncio"):
            assert not logging.getLogger(name).isEnabledFor(logging.ERROR), name
        assert not logging.getLogger("tornado.application").isEnabledFor(logging.ERROR)
        assert logging.getLogger("fsspec").level == logging.CRITICAL  # never made louder
        assert logging.getLogger("bokeh").getEffectiveLevel() == logging.ERROR


def test_importing_glshade_logs_changes_no_logger():
    code = "import logging, glshade.logs; print(logging.getLogger('asyncio').level)"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "0"


LOCAL_WORKERS = textwrap.dedent(
    """
    import logging, sys
    from glshade.errors import GlshadeError
    from glshade.measure.cluster import DaskExecutor
    from glshade.measure.executors import Distribution
    from glshade.measure.scheduler import check_scheduler
    from glshade.sweep.spec import spec_from_dict

    def noise():
        for name in ("distributed.worker", "distributed.core", "tornado.application", "asyncio"):
            logging.getLogger(name).error("NOISE from %s", name)
        print("WORKER-STDERR-REACHES-US", file=sys.stderr, flush=True)

    if __name__ == "__main__":
        spec = spec_from_dict({"size": 32, "grid": {"camera.theta_deg": [45]}})
        with DaskExecutor(Distribution(workers=1)) as executor:
            rows = list(executor.rows([p.case for p in spec.cases()], spec.settings, False))
            executor.client.run(noise)
            logging.getLogger("distributed.nanny").error("NOISE from this process")
            (worker,) = executor.client.scheduler_info()["workers"]
            try:
                check_scheduler(worker, 10)
            except GlshadeError as exc:
                print(exc)
        print("rows", len(rows))
    """
)


def test_local_workers_measure_and_shut_down_without_a_log_line(tmp_path):
    (tmp_path / "local.py").write_text(LOCAL_WORKERS)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    run = subprocess.run(
        [sys.executable, "local.py"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.splitlines()[-1] == "rows 1"
    assert "not a Dask scheduler: a Dask Worker answers at" in run.stdout
    assert run.stderr == "WORKER-STDERR-REACHES-US\n"  # and no NOISE, no traceback
