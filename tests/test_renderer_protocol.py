"""Both renderers are :class:`glshade.rendering.Renderer`s, the protocol the measuring
code takes: the GL one and the NumPy float64 oracle's, at run time (``isinstance``) and
for mypy (the assignments under ``TYPE_CHECKING`` below, which
:func:`test_both_renderers_satisfy_the_protocol_for_mypy` has mypy check)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from glshade.oracle.renderer import OracleRenderer
from glshade.rendering import Renderer as RendererProtocol

if TYPE_CHECKING:  # mypy: each class is a RendererProtocol by its shape alone
    from glshade.gpu.renderer import Renderer

    def _gl(renderer: Renderer) -> RendererProtocol:
        return renderer

    def _oracle(renderer: OracleRenderer) -> RendererProtocol:
        return renderer


ROOT = Path(__file__).resolve().parents[1]


def test_the_gl_renderer_is_a_renderer(renderer):
    assert isinstance(renderer, RendererProtocol)


def test_the_oracle_is_a_renderer():
    with OracleRenderer() as oracle:
        assert isinstance(oracle, RendererProtocol)


def test_an_object_without_a_renderers_members_is_not_one():
    class Drawing:
        memory_budget_bytes = 1 << 20

        def release(self) -> None:
            pass

    assert not isinstance(Drawing(), RendererProtocol)


@pytest.mark.slow  # mypy: about 7 s
def test_both_renderers_satisfy_the_protocol_for_mypy(tmp_path, monkeypatch):
    api = pytest.importorskip("mypy.api")
    # glshade's own sources, typed (as installed it has no py.typed: mypy would see Any)
    monkeypatch.setenv("MYPYPATH", str(ROOT / "src"))
    out, err, code = api.run(
        [
            "--config-file",
            str(ROOT / "pyproject.toml"),
            "--follow-imports",
            "silent",
            "--cache-dir",
            str(tmp_path / "mypy_cache"),
            str(Path(__file__)),
        ]
    )
    assert code == 0, out + err
