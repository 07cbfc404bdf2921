"""The composer's compiled templates kept on disk (glshade.gpu.template_cache): the composed
source is the same with the cache as without it, whatever the cache holds. No GPU."""

from __future__ import annotations

import os

import jinja2
import pytest

from glshade import cache
from glshade.gpu import compose as composer
from glshade.gpu.compose import ShaderFeatures
from glshade.gpu.template_cache import TemplateCache
from glshade.scene import paper_scene

SCENES = (
    paper_scene("flat", 45.0, 4.0, 0.005),
    paper_scene("sphere", 5.0, 1.0, 0.005),
    paper_scene("cylinder", 15.0, 9.0, 0.003).without_defect(),
)


def _sources(monkeypatch, cache_dir: str) -> list[tuple[str, str]]:
    """Every scene's program (image and uv) composed afresh in a new environment whose
    cache is ``cache_dir`` ("" for none)."""
    monkeypatch.setenv(cache.CACHE_ENV, cache_dir)
    composer.compose.cache_clear()
    composer._environment.cache_clear()
    try:
        return [
            composer.compose(ShaderFeatures.from_scene(scene, outputs))
            for scene in SCENES
            for outputs in (("image",), ("uv",))
        ]
    finally:
        composer.compose.cache_clear()
        composer._environment.cache_clear()


def _entries(folder) -> dict[str, int]:
    """The compiled templates in ``folder``, by name: each one's inode (a new one when
    the entry was written again)."""
    return {p.name: p.stat().st_ino for p in folder.iterdir() if p.name.endswith(".cache")}


def test_cached_composition_equals_uncached(monkeypatch, tmp_path):
    plain = _sources(monkeypatch, "")
    cold = _sources(monkeypatch, str(tmp_path))
    entries = _entries(tmp_path / "templates")
    warm = _sources(monkeypatch, str(tmp_path))
    assert entries, "the cold run must have written compiled templates"
    assert _entries(tmp_path / "templates") == entries  # read, not written again
    assert cold == plain
    assert warm == plain


def test_damaged_entries_are_compiled_again(monkeypatch, tmp_path):
    plain = _sources(monkeypatch, "")
    _sources(monkeypatch, str(tmp_path))
    for name in _entries(tmp_path / "templates"):
        (tmp_path / "templates" / name).write_bytes(b"not a compiled template")
    assert _sources(monkeypatch, str(tmp_path)) == plain


def _render(folder, cache_dir, name="t.txt", **options) -> str:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(folder)),
        bytecode_cache=TemplateCache(cache.open_private_folder(cache_dir), options),
        **options,
    )
    return env.get_template(name).render(x=1)


def test_a_changed_file_is_compiled_again(tmp_path):
    (tmp_path / "c").mkdir()
    (tmp_path / "t.txt").write_text("first {{ x }}")
    assert _render(tmp_path, tmp_path / "c") == "first 1"
    (tmp_path / "t.txt").write_text("second {{ x }}")
    assert _render(tmp_path, tmp_path / "c") == "second 1"


def test_environments_with_other_delimiters_never_share_entries(tmp_path):
    """The compiled code depends on the delimiters: an entry made with ``<< >>`` must not
    be run by an environment whose variables are ``{{ }}``, and the other way round."""
    (tmp_path / "c").mkdir()
    (tmp_path / "t.txt").write_text("<< x >> {{ x }}")
    angled = {"variable_start_string": "<<", "variable_end_string": ">>"}
    assert _render(tmp_path, tmp_path / "c", **angled) == "1 {{ x }}"
    assert _render(tmp_path, tmp_path / "c") == "<< x >> 1"
    assert _render(tmp_path, tmp_path / "c", **angled) == "1 {{ x }}"
    assert len(_entries(tmp_path / "c")) == 2


def test_an_unwritable_cache_never_fails_composition(tmp_path):
    (tmp_path / "t.txt").write_text("kept {{ x }}")
    gone = tmp_path / "gone"
    gone.mkdir()
    bytecode = TemplateCache(cache.open_private_folder(gone), {})
    gone.rmdir()  # writing the entry now fails
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(tmp_path)), bytecode_cache=bytecode)
    assert env.get_template("t.txt").render(x=1) == "kept 1"


def test_cache_folder(monkeypatch, tmp_path):
    monkeypatch.setenv(cache.CACHE_ENV, "")
    assert cache.cache_dir("templates") is None
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "root"))
    folder = cache.cache_dir("templates")
    assert folder.path == tmp_path / "root" / "templates" and folder.path.is_dir()
    assert os.path.samestat(os.fstat(folder.fd), os.stat(folder.path))
    assert folder.path.stat().st_mode & 0o077 == 0
    folder.path.chmod(0o777)  # others may write there: its entries are code, not used
    assert cache.cache_dir("templates") is None
    (tmp_path / "file").write_text("")
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "file"))
    assert cache.cache_dir("templates") is None  # a folder cannot be made under a file
    monkeypatch.delenv(cache.CACHE_ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_root() == tmp_path / "xdg" / "glshade"


@pytest.mark.parametrize("value", ["", "  "])
def test_empty_cache_variable_turns_the_cache_off(monkeypatch, value):
    monkeypatch.setenv(cache.CACHE_ENV, value)
    assert cache.cache_root() is None
