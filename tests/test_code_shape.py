"""The code's shape, kept: no function in the package runs over a screen (80 lines), and
the suite's own markers say what a test needs (``gl``, ``subprocess``, ``slow``:
``tests/conftest.py`` and ``pyproject.toml``)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import glshade

PACKAGE = Path(glshade.__file__).resolve().parent
#: The most lines a function (its decorators aside, its docstring included) may take.
MAX_FUNCTION_LINES = 80


def _long_functions() -> list[str]:
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    found.append(f"{path.relative_to(PACKAGE)}:{node.name} ({lines} lines)")
    return found


def test_no_function_runs_over_a_screen():
    assert _long_functions() == []


def test_a_test_that_draws_is_marked_gl(renderer, request):
    assert request.node.get_closest_marker("gl") is not None
    assert request.node.get_closest_marker("subprocess") is None  # no process here


def test_a_test_without_gl_is_not_marked(request):
    assert request.node.get_closest_marker("gl") is None


@pytest.mark.parametrize("marker", ["gl", "subprocess", "slow"])
def test_the_markers_are_registered(pytestconfig, marker):
    assert any(line.startswith(f"{marker}:") for line in pytestconfig.getini("markers"))
