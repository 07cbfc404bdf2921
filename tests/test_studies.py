"""The paper's study by instrument (``glshade paper --method NAME``): the studies come
from the ``glshade.studies`` registry, one per registered instrument at most."""

from __future__ import annotations

import argparse

import pytest

from glshade.app import studies
from glshade.app.studies import StudyKind, refuse_other_flags, study_kind, study_kinds
from glshade.errors import GlshadeError, GlshadeWarning
from glshade.instruments.registry import method_names


@pytest.fixture
def fresh_registry():
    studies.study_kinds.cache_clear()
    yield
    studies.study_kinds.cache_clear()


def test_glshade_studies_are_the_builtin_instruments():
    kinds = study_kinds()
    assert tuple(kinds) == ("paper", "pmd")
    assert all(kind.name == name and name in method_names() for name, kind in kinds.items())
    with pytest.raises(GlshadeError, match="--method: must be one of paper, pmd, got 'x'"):
        study_kind("x")


def test_a_flag_of_another_study_is_refused_naming_its_instrument():
    parser = argparse.ArgumentParser()
    for kind in study_kinds().values():
        kind.add_flags(parser)
    args = parser.parse_args(["--shifts", "5"])
    refuse_other_flags(args, study_kind("pmd"))  # its own flag
    with pytest.raises(GlshadeError) as raised:
        refuse_other_flags(args, study_kind("paper"))
    assert str(raised.value) == (
        "--shifts: belongs to phase measuring (--method pmd), not to --method paper"
    )


class _Orphan(StudyKind):
    name = "nobody"
    writes = "nothing"

    def prepared(self, args, plan, workers):
        return None

    def run(self, args, plan, prepared):
        return 0


ORPHAN = _Orphan()


def test_a_plugin_study_without_its_instrument_is_left_out_with_one_warning(
    monkeypatch, fresh_registry
):
    points = [("nobody", f"{__name__}:ORPHAN"), ("pmd", f"{__name__}:ORPHAN")]
    monkeypatch.setattr(studies, "_plugin_points", lambda: points)
    with pytest.warns(GlshadeWarning) as caught:
        kinds = study_kinds()
    assert tuple(kinds) == ("paper", "pmd") and not isinstance(kinds["pmd"], _Orphan)
    said = [str(w.message) for w in caught]
    assert len(said) == 2 and all("left out: no instrument" in line for line in said)


def test_a_plugin_study_that_is_not_a_study_kind_is_left_out(monkeypatch, fresh_registry):
    monkeypatch.setattr(studies, "_plugin_points", lambda: [("paper", "builtins:object")])
    monkeypatch.setattr(studies, "BUILTIN_STUDIES", {"pmd": studies.BUILTIN_STUDIES["pmd"]})
    with pytest.warns(GlshadeWarning, match=r"study plug-in paper \(builtins:object\) left out"):
        assert tuple(study_kinds()) == ("pmd",)
