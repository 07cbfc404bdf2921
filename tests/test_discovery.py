"""Finding the components without importlib.metadata when only glshade declares them
(glshade.components.registry.only_builtin_declared): the short cut is taken only where
``importlib.metadata.entry_points`` would return glshade's own entry point alone. No GPU."""

from __future__ import annotations

import sys
import zipfile
from importlib.metadata import entry_points

import pytest

from glshade.components import registry as reg

GROUP = f"[{reg.ENTRY_POINT_GROUP}]\n"


def _declared_by_metadata(path: list[str]) -> list[tuple[str, str]]:
    """The oracle: what importlib.metadata finds on ``path``."""
    saved = sys.path[:]
    sys.path[:] = path
    try:
        return [(p.name, p.value) for p in entry_points(group=reg.ENTRY_POINT_GROUP)]
    finally:
        sys.path[:] = saved


def _dist(folder, name: str, text: str | None, suffix: str = ".dist-info"):
    info = folder / f"{name}-1.0{suffix}"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
    if text is not None:
        (info / "entry_points.txt").write_text(text)
    return info


def _builtin_text() -> str:
    name, value = reg.BUILTIN_ENTRY_POINT
    return f"[console_scripts]\nglshade = glshade.app.cli:main\n\n{GROUP}{name} = {value}\n"


def test_this_environment_takes_the_short_cut_and_finds_the_same_components():
    """glshade is installed here (its entry point is how the CLI finds anything)."""
    assert _declared_by_metadata(sys.path) == [reg.BUILTIN_ENTRY_POINT]
    assert reg.only_builtin_declared()
    names = [(c.slot, c.name) for c in reg.discovered()]
    full = []
    for point in reg._entry_points():
        full.extend(reg._instances(point.load(), point.name))
    assert sorted(names) == sorted((c.slot, c.name) for c in full)


def _layouts(tmp_path):
    """sys.path layouts: (description, path)."""
    only = tmp_path / "only"
    _dist(only, "glshade", _builtin_text())
    _dist(only, "numpy_like", "[console_scripts]\nx = y:z\n")
    _dist(only, "no_entry_points", None)
    plugin = tmp_path / "plugin"
    _dist(plugin, "glshade_plug", f"{GROUP}plug = glshade_plug:COMPONENTS\n")
    egg_plugin = tmp_path / "egg_plugin"
    _dist(egg_plugin, "old_plug", f"{GROUP}old = old_plug\n", suffix=".egg-info")
    first_without = tmp_path / "first_without"
    _dist(first_without, "glshade", "[console_scripts]\nglshade = glshade.app.cli:main\n")
    more = tmp_path / "more"
    _dist(more, "glshade", _builtin_text() + "extra = glshade.extra:COMPONENTS\n")
    archive = tmp_path / "plug.zip"
    with zipfile.ZipFile(archive, "w") as z:
        z.writestr("zipped-1.0.dist-info/METADATA", "Metadata-Version: 2.1\nName: zipped\n")
        z.writestr("zipped-1.0.dist-info/entry_points.txt", f"{GROUP}z = zipped\n")
    plain_zip = tmp_path / "plain.zip"
    with zipfile.ZipFile(plain_zip, "w") as z:
        z.writestr("module.py", "")
    missing = str(tmp_path / "missing")
    return [
        ("glshade alone", [str(only), missing]),
        ("a plug-in after it", [str(only), str(plugin)]),
        ("an egg-info plug-in", [str(egg_plugin), str(only)]),
        ("a zip on the path", [str(only), str(archive)]),
        ("a zip without distributions", [str(only), str(plain_zip)]),  # not looked into
        ("a first glshade without the group", [str(first_without), str(only)]),
        ("glshade declaring more", [str(more)]),
        ("no glshade", [str(plugin)]),
        ("nothing", [missing]),
    ]


def test_the_short_cut_is_taken_only_where_importlib_metadata_agrees(tmp_path):
    taken = {}
    for label, path in _layouts(tmp_path):
        short = reg.only_builtin_declared(path)
        taken[label] = short
        if short:  # else the full look-up runs, whatever it finds
            assert _declared_by_metadata(path) == [reg.BUILTIN_ENTRY_POINT], label
    assert taken == {
        "glshade alone": True,
        "a plug-in after it": False,
        "an egg-info plug-in": False,
        "a zip on the path": False,
        "a zip without distributions": False,
        "a first glshade without the group": False,
        "glshade declaring more": False,
        "no glshade": False,
        "nothing": False,
    }


def test_another_finder_of_distributions_means_the_full_look_up(monkeypatch, tmp_path):
    class Finder:
        def find_spec(self, *args):
            return None

        def find_distributions(self, *args):
            return iter(())

    path = _layouts(tmp_path)[0][1]
    assert reg.only_builtin_declared(path)
    monkeypatch.setattr(sys, "meta_path", [*sys.meta_path, Finder()])
    assert not reg.only_builtin_declared(path)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (f"# a comment\n{GROUP}  a = b:c  \n\n[other]\nd = e\n", [("a", "b:c")]),
        (f"[other]\nd = e\n{GROUP}\n", []),
    ],
)
def test_entry_points_text_is_read_as_importlib_metadata_reads_it(tmp_path, text, expected):
    info = _dist(tmp_path, "some", text)
    assert reg._declared(str(info)) == expected
    assert _declared_by_metadata([str(tmp_path)]) == expected


def test_a_checkout_that_is_not_installed_has_its_own_components(monkeypatch):
    """``PYTHONPATH=src`` without ``pip install``: no distribution declares glshade's entry
    point, and its built-in components are there all the same (a GPU machine ran the
    benchmarks so, and found none: 'emitter.kind: must be one of , got stripes')."""
    monkeypatch.setattr(reg, "only_builtin_declared", lambda path=None: False)
    monkeypatch.setattr(reg, "_entry_points", lambda: [])
    names = {(c.slot, c.name) for c in reg.discovered()}
    assert ("emitter", "stripes") in names and ("surface", "flat") in names
