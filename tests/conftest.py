"""Shared fixtures: one GL context and renderer per test session, GL error checks. The
snapshot tests' options (``--glshade-update``, ``--glshade-results``) are glshade's
pytest plugin's (glshade.snapshot.plugin)."""

from __future__ import annotations

import pytest

from glshade.gpu.context import GLContext
from glshade.gpu.renderer import Renderer


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
