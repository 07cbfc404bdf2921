"""The compiled-template cache (glshade.cache, glshade.gpu.template_cache) runs no code but
the user's own: each test plants what an attacker could (a forged or copied entry, a FIFO,
a link, a folder of someone else's, a relative cache path, a folder swapped after the
check) and checks that none of it is read as code, nothing is written through it, and
composition neither fails nor hangs. No GPU: the composer needs Jinja only."""

from __future__ import annotations

import hashlib
import hmac
import os
import pickle
import shutil
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import jinja2
import pytest
from jinja2.bccache import Bucket, bc_magic
from tests.test_template_cache import _entries, _sources

from glshade import cache
from glshade.app.cli import guarded_warnings
from glshade.errors import GlshadeWarning
from glshade.gpu import compose as composer
from glshade.gpu.compose import ShaderFeatures
from glshade.gpu.template_cache import ENTRY_HEADER, TemplateCache, folder_key
from glshade.scene import paper_scene

pytestmark = pytest.mark.skipif(not cache.descriptors_supported(), reason="POSIX only")


class _Plant:
    """A pickle that makes folder ``path`` when it is unpickled: code an entry could run."""

    def __init__(self, path: Path) -> None:
        self.path = str(path)

    def __reduce__(self):
        return (os.mkdir, (self.path,))


def _evil_payload(marker: Path) -> bytes:
    """A Jinja bucket whose unpickling makes ``marker``."""
    return bc_magic + pickle.dumps(_Plant(marker), protocol=2)


@pytest.fixture
def loads(monkeypatch) -> list[bytes]:
    """Every byte string that reaches Jinja's unpickling (``bytecode_from_string``)."""
    seen: list[bytes] = []
    real = Bucket.bytecode_from_string

    def spy(self, string: bytes) -> None:
        seen.append(string)
        real(self, string)

    monkeypatch.setattr(Bucket, "bytecode_from_string", spy)
    return seen


def test_the_evil_payload_would_run_if_unpickled(tmp_path):
    """The control: the payload the tests below plant does run code when Jinja reads it."""
    marker = tmp_path / "ran"
    Bucket(jinja2.Environment(), "k", "sum").bytecode_from_string(_evil_payload(marker))
    assert marker.is_dir()


@pytest.mark.parametrize("form", ["wrong MAC", "Jinja's own format"])
def test_a_forged_entry_never_runs(monkeypatch, tmp_path, form):
    plain = _sources(monkeypatch, "")
    _sources(monkeypatch, str(tmp_path / "root"))
    marker = tmp_path / "ran"
    folder = tmp_path / "root" / "templates"
    for name in _entries(folder):
        evil = _evil_payload(marker)
        forged = ENTRY_HEADER + bytes(32) + evil if form == "wrong MAC" else evil
        (folder / name).write_bytes(forged)
    assert _sources(monkeypatch, str(tmp_path / "root")) == plain
    assert not marker.exists()
    assert all((folder / name).read_bytes().startswith(ENTRY_HEADER) for name in _entries(folder))


def test_a_copied_folder_key_included_is_not_trusted(monkeypatch, tmp_path, loads):
    """An entry signed with the very key it ships with (an extracted archive, a folder
    copied from another machine) is compiled again, never run: the key's identity on this
    file system is part of the MAC. In the folder it was signed in, it would run."""
    plain = _sources(monkeypatch, "")
    _sources(monkeypatch, str(tmp_path / "origin"))
    origin = tmp_path / "origin" / "templates"
    held = cache.open_private_folder(origin)
    key = folder_key(held.fd)
    held.close()
    marker = tmp_path / "ran"
    assert key is not None
    for name in _entries(origin):
        payload = _evil_payload(marker)
        mac = hmac.new(key, name.encode() + b"\0" + payload, hashlib.sha256).digest()
        (origin / name).write_bytes(ENTRY_HEADER + mac + payload)
    shutil.copytree(tmp_path / "origin", tmp_path / "copy")  # modes and owner kept
    copied = _entries(tmp_path / "copy" / "templates")
    loads.clear()
    assert _sources(monkeypatch, str(tmp_path / "copy")) == plain
    assert not marker.exists() and _evil_payload(marker) not in loads
    after = _entries(tmp_path / "copy" / "templates")
    assert after.keys() == copied.keys()
    assert all(after[name] != copied[name] for name in copied)  # each one written anew
    _sources(monkeypatch, str(tmp_path / "origin"))  # the limit: a forger with the key
    assert marker.is_dir()


def _render(templates: Path, folder: cache.PrivateFolder | None) -> str:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(templates)),
        bytecode_cache=None if folder is None else TemplateCache(folder, {}),
    )
    return env.get_template("t.txt").render(x=1)


@pytest.fixture
def warm(tmp_path) -> tuple[Path, Path]:
    """A template and a cache folder holding its compiled entry (and the key)."""
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "t.txt").write_text("value {{ x }}")
    folder = tmp_path / "c"
    folder.mkdir(mode=0o700)
    assert _render(tmp_path / "src", cache.open_private_folder(folder)) == "value 1"
    assert len(_entries(folder)) == 1
    return tmp_path / "src", folder


def test_an_authentic_entry_is_read(warm, loads):
    templates, folder = warm
    assert _render(templates, cache.open_private_folder(folder)) == "value 1"
    assert len(loads) == 1


def _fifo(path: Path) -> None:
    path.unlink()
    os.mkfifo(path, 0o600)


def _link_elsewhere(path: Path) -> None:
    other = path.parent.parent / "elsewhere"
    path.rename(other)
    path.symlink_to(other)


def _group_writable(path: Path) -> None:
    path.chmod(0o620)


def _oversized(path: Path) -> None:
    with path.open("ab") as file:
        file.truncate(4 * 2**20 + 1)


@pytest.mark.parametrize("plant", [_fifo, _link_elsewhere, _group_writable, _oversized])
def test_an_entry_that_is_not_a_private_file_is_ignored(warm, loads, plant):
    """A FIFO (which would block a plain open), a link, an entry others may write, one of
    more than 4 MiB: compiled again, never read, never waited on."""
    templates, folder = warm
    (name,) = _entries(folder)
    plant(folder / name)
    with _deadline(20):
        assert _render(templates, cache.open_private_folder(folder)) == "value 1"
    assert not loads


def test_a_fifo_as_the_key_turns_the_cache_off_without_waiting(warm, loads):
    templates, folder = warm
    _fifo(folder / "key")
    with _deadline(20):
        assert _render(templates, cache.open_private_folder(folder)) == "value 1"
    assert not loads


class _Hung(Exception):
    pass


class _deadline:
    """Fails the test (instead of hanging it) when the block lasts ``seconds``."""

    def __init__(self, seconds: int) -> None:
        self.seconds = seconds

    def __enter__(self) -> None:
        def expired(signum, frame):
            raise _Hung(f"still waiting after {self.seconds} s")

        self.previous = signal.signal(signal.SIGALRM, expired)
        signal.alarm(self.seconds)

    def __exit__(self, *exc: object) -> None:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, self.previous)


def test_a_root_of_someone_else_is_refused(monkeypatch, tmp_path, loads):
    plain = _sources(monkeypatch, "")
    root = tmp_path / "root"
    _sources(monkeypatch, str(root))
    before = _entries(root / "templates")
    real_uid = os.getuid()
    monkeypatch.setattr(os, "getuid", lambda: real_uid + 1)  # as seen by another user
    monkeypatch.setenv(cache.CACHE_ENV, str(root))
    assert cache.cache_dir("templates") is None
    loads.clear()
    assert _sources(monkeypatch, str(root)) == plain
    assert not loads and _entries(root / "templates") == before


@pytest.mark.parametrize("mode", [0o770, 0o707])
def test_a_root_others_may_write_to_is_refused(monkeypatch, tmp_path, mode):
    plain = _sources(monkeypatch, "")
    root = tmp_path / "shared"
    root.mkdir()
    root.chmod(mode)
    assert _sources(monkeypatch, str(root)) == plain
    assert list(root.iterdir()) == []


def test_a_templates_link_is_refused_and_nothing_is_written_through_it(monkeypatch, tmp_path):
    """The root's owner plants ``templates`` -> the victim's private folder: the cache is
    off, and the private folder stays as it was."""
    plain = _sources(monkeypatch, "")
    private = tmp_path / "private"
    private.mkdir(mode=0o700)
    root = tmp_path / "root"
    root.mkdir(mode=0o700)
    (root / "templates").symlink_to(private)
    monkeypatch.setenv(cache.CACHE_ENV, str(root))
    assert cache.cache_dir("templates") is None
    assert _sources(monkeypatch, str(root)) == plain
    assert list(private.iterdir()) == []


def test_a_root_that_is_a_link_is_refused(monkeypatch, tmp_path):
    private = tmp_path / "private"
    private.mkdir(mode=0o700)
    (tmp_path / "root").symlink_to(private)
    monkeypatch.setenv(cache.CACHE_ENV, str(tmp_path / "root"))
    assert cache.cache_dir("templates") is None
    assert list(private.iterdir()) == []


def test_a_relative_cache_variable_turns_the_cache_off_with_one_warning(
    monkeypatch, tmp_path, capsys
):
    """A project folder that ships ``proj-cache/templates`` is never read, however its
    entries look: the relative path is refused before any file is opened."""
    plain = _sources(monkeypatch, "")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "proj-cache" / "templates").mkdir(parents=True, mode=0o700)
    monkeypatch.setenv(cache.CACHE_ENV, "proj-cache")
    with pytest.warns(GlshadeWarning, match=r"GLSHADE_CACHE_DIR='proj-cache' .* absolute"):
        assert cache.cache_root() is None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", GlshadeWarning)
        assert _sources(monkeypatch, "proj-cache") == plain
    assert list((tmp_path / "proj-cache" / "templates").iterdir()) == []
    capsys.readouterr()
    with guarded_warnings(verbose=False):
        warnings.simplefilter("always")
        cache.cache_root()
        cache.cache_root()
    lines = capsys.readouterr().err.splitlines()
    assert lines == [
        "glshade: warning: GLSHADE_CACHE_DIR='proj-cache' is a relative path; it must be "
        "absolute (or start with ~): glshade keeps no cache in this run"
    ]


def test_a_home_relative_cache_variable_is_expanded(monkeypatch, tmp_path):
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv(cache.CACHE_ENV, "~/glshade-cache")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert cache.cache_root() == tmp_path / "glshade-cache"


def test_a_folder_swapped_after_the_check_is_never_used(monkeypatch, tmp_path):
    """Between the cache's check and its first read, ``templates`` is renamed away and
    another folder put in its place (after each environment's check): the entries go to
    the folders that were checked (the descriptors held), none to the newcomer."""
    plain = _one_program(monkeypatch, "")
    root = tmp_path / "root"
    real = composer._template_cache
    swapped: list[Path] = []

    def opened_then_swapped():
        bytecode = real()
        checked = root / f"checked-{len(swapped)}"
        (root / "templates").rename(checked)
        (root / "templates").mkdir(mode=0o700)
        swapped.append(checked)
        return bytecode

    monkeypatch.setattr(composer, "_template_cache", opened_then_swapped)
    assert _one_program(monkeypatch, str(root)) == plain
    assert swapped and all(_entries(checked) for checked in swapped)
    assert list((root / "templates").iterdir()) == []


def _one_program(monkeypatch, cache_dir: str) -> str:
    """The sphere's image program composed afresh (one environment) with the cache in
    ``cache_dir`` ("" for none)."""
    monkeypatch.setenv(cache.CACHE_ENV, cache_dir)
    composer.compose.cache_clear()
    composer._environment.cache_clear()
    try:
        return composer.compose(ShaderFeatures.from_scene(paper_scene("sphere"), ("image",)))
    finally:
        composer.compose.cache_clear()
        composer._environment.cache_clear()


def test_entries_are_reused_by_the_next_process(tmp_path):
    """Two processes one after the other: the second reads the first one's entries (none
    is written again) and composes the same source."""
    code = (
        "from glshade.gpu.compose import ShaderFeatures, compose; "
        "from glshade.scene import paper_scene; "
        "print(hash(compose(ShaderFeatures.from_scene(paper_scene('sphere'), ('image',)))))"
    )
    env = {**os.environ, cache.CACHE_ENV: str(tmp_path / "root"), "PYTHONHASHSEED": "0"}

    def run() -> str:
        done = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
        )
        assert done.returncode == 0, done.stderr
        return done.stdout

    first = run()
    entries = _entries(tmp_path / "root" / "templates")
    assert entries
    assert run() == first
    assert _entries(tmp_path / "root" / "templates") == entries
