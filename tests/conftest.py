"""Shared fixtures: one GL context and renderer per test session, GL error checks. The
snapshot tests' options (``--glshade-update``, ``--glshade-results``) are glshade's
pytest plugin's (glshade.snapshot.plugin).

The markers ``gl`` and ``subprocess`` are set here from what a test uses (the GL context
fixture; a module that starts processes), ``slow`` by hand on the slowest tests, so that
``-m "not slow"``, ``-m "not gl"`` or ``-m "not subprocess"`` select a quicker part."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from glshade.gpu.context import GLContext
from glshade.gpu.renderer import Renderer


@pytest.fixture(scope="session")
def sofast_dir() -> Path:
    """The real SOFAST measurement's folder (the repository's ``../shared/sofast``, or
    ``shared/sofast`` inside it); the test is skipped where it is absent."""
    here = Path(__file__).resolve().parents[1]
    for folder in (here.parent / "shared" / "sofast", here / "shared" / "sofast"):
        if (folder / "measurement_facet.h5").exists():
            return folder
    pytest.skip("SOFAST data (shared/sofast) absent")


@pytest.fixture(scope="session")
def gl_context():
    with GLContext() as context:
        yield context


@pytest.fixture(scope="session")
def _session_renderer(gl_context):
    with Renderer(gl_context) as renderer:
        yield renderer


@pytest.fixture
def renderer(_session_renderer, gl_context):
    """The session's renderer; GL must report no error before and after each test."""
    gl_context.check_error("the previous test")
    yield _session_renderer
    gl_context.check_error("this test")


def pytest_collection_modifyitems(config, items):
    """``gl`` on every test that needs the GL context (directly or through ``renderer``);
    ``subprocess`` on the tests of a module that starts processes (it imports
    :mod:`subprocess`, the suite's :func:`glshade_process.run_glshade` or
    :func:`plugin_venv.glshade_in`)."""
    for item in items:
        if "gl_context" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.gl)
        module = getattr(item, "module", None)
        if module is not None and (
            getattr(module, "subprocess", None) is subprocess
            or hasattr(module, "run_glshade")
            or hasattr(module, "glshade_in")
        ):
            item.add_marker(pytest.mark.subprocess)
