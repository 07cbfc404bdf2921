"""The instrument interface and its registry: glshade's two instruments registered through
it, declarations checked, a broken plug-in left out with one warning, settings validated
by their declarations, case identities unchanged, the settings page generated."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path
from typing import Any, ClassVar

import pytest

from glshade.errors import GlshadeError, SceneError
from glshade.instruments import registry as reg
from glshade.instruments.base import Goal, Instrument
from glshade.instruments.pmd.settings import PmdSettings
from glshade.instruments.record import Measurement, PmdMeasurement
from glshade.instruments.registry import declaration_problem, instrument, instrument_for
from glshade.instruments.settings_doc import settings_markdown
from glshade.metrics.visibility import MetricSettings
from glshade.scene import paper_scene
from glshade.sweep.spec import case_id


def test_the_two_builtin_instruments_are_registered_by_name_and_by_settings():
    assert reg.method_names() == ("paper", "pmd")
    assert instrument_for(MetricSettings()).record_type is Measurement
    assert instrument_for(PmdSettings()).record_type is PmdMeasurement
    assert instrument("pmd").prepared(paper_scene()).emitter.kind == "fringes"
    with pytest.raises(GlshadeError, match="method: must be one of paper, pmd, got 'laser'"):
        instrument("laser")
    with pytest.raises(GlshadeError, match="settings: must be the settings of an instrument"):
        instrument_for(object())


@dataclasses.dataclass(frozen=True)
class _Settings:
    level: float = 0.5


class _Toy(Instrument):
    name: ClassVar[str] = "toy"
    title: ClassVar[str] = "a toy"
    settings_type: ClassVar[type] = _Settings
    record_type = Measurement
    outputs: ClassVar[tuple[str, ...]] = ("visibility_px", "status")

    def measure(self, renderer: Any, scene: Any, settings: Any) -> Any:
        raise NotImplementedError

    def record(self, scene: Any, result: Any, trace_s: float = 0.0) -> Any:
        raise NotImplementedError


def _variant(**attributes: Any) -> Instrument:
    return type("Variant", (_Toy,), attributes)()


@pytest.mark.parametrize(
    "attributes, words",
    [
        ({"name": "Bad Name"}, "instrument name 'Bad Name'"),
        ({"settings_type": dict}, "settings_type must be a dataclass"),
        ({"record_type": dict}, "record_type must be a Record"),
        ({"outputs": ("no_such_column",)}, "not columns of its record"),
        ({"goals": (Goal("g", "no_such_column", "toy"),)}, "goal 'g' reads no column"),
        ({"goals": (Goal("g", "visibility_px", "paper"),)}, "goal 'g' reads no column"),
    ],
)
def test_a_malformed_declaration_is_named_in_one_line(attributes, words):
    assert declaration_problem(_Toy()) is None
    problem = declaration_problem(_variant(**attributes))
    assert problem is not None and words in problem and "\n" not in problem


def test_a_malformed_offer_of_views_is_named_in_one_line():
    from glshade.instruments.base import InstrumentView, InstrumentViews

    view = InstrumentView("toy-map", "toy", lambda scene, result: None)
    good = InstrumentViews("toy", (view,), lambda scene, result, missing: [])
    assert declaration_problem(_variant(views=lambda self: good)) is None
    offers = {
        "must give InstrumentViews": object(),
        "names repeat": InstrumentViews("toy", (view, view), good.readout),
        "case size": InstrumentViews("toy", (view,), good.readout, size=4),
    }
    for words, offer in offers.items():
        problem = declaration_problem(_variant(views=lambda self, offer=offer: offer))
        assert problem is not None and words in problem


def test_a_plugin_that_fails_to_load_is_left_out_with_one_warning(monkeypatch, tmp_path):
    (tmp_path / "broken_instrument.py").write_text("raise SystemExit(3)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    points = [*reg._points(), ("broken", "broken_instrument:make", False)]
    monkeypatch.setattr(reg, "_points", lambda: points)
    reg.instruments.cache_clear()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            found = reg.instruments()
        assert found.names() == ("paper", "pmd")
        lines = [str(w.message) for w in caught]
        assert len(lines) == 1 and "broken" in lines[0] and "SystemExit" in lines[0]
    finally:
        reg.instruments.cache_clear()


def test_settings_are_checked_by_their_declarations():
    with pytest.raises(SceneError, match=r"measure.threshold: must be in \(0, 1\), got 2"):
        MetricSettings(threshold=2.0)
    with pytest.raises(SceneError, match=r"measure.keep_fraction: must be in \(0, 1\]"):
        MetricSettings(keep_fraction=0.0)
    assert MetricSettings(keep_fraction=1.0).keep_fraction == 1.0
    with pytest.raises(SceneError, match="measure.heights: must be one of least-squares"):
        PmdSettings(heights="poisson")
    with pytest.raises(SceneError, match="measure.plane_sigmas: must be below"):
        PmdSettings(plane_sigmas=6.0)


def test_case_identities_are_what_they_were_before_instruments_were_plugins():
    """Hashes computed with the code before the registry: a sweep of either instrument
    resumes its cases (the PMD ones since PMD_VERSION 3, whose noise is drawn on the GPU:
    an older PMD sweep's cases are measured again, never mixed with new ones)."""
    scene = paper_scene("sphere", 30.0, 4.0, 0.005).with_size(64)
    assert case_id(scene, MetricSettings()) == "733f7bdd5aa5c755"
    assert case_id(scene, PmdSettings()) == "d823db06697d4f3d"
    assert case_id(scene, MetricSettings(threshold=0.4, otsu=True)) == "08566db82967f6de"
    changed = PmdSettings(heights="frankot-chellappa", min_modulation=0.01)
    assert case_id(scene, changed) == "02e314e6af34c141"


def test_the_settings_page_is_generated_from_the_declarations():
    page = Path(__file__).resolve().parents[1] / "docs" / "measure-settings.md"
    assert page.read_text() == settings_markdown(), (
        "regenerate: python -m glshade.instruments.settings_doc > docs/measure-settings.md"
    )


def test_set_measure_is_the_measuring_instruments_and_refused_where_nothing_measures(
    tmp_path, capsys
):
    from glshade.app.cli import main

    out = tmp_path / "frame.png"
    assert main(["render", "--size", "16", "-o", str(out), "--set", "measure.threshold=0.3"]) == 2
    err = capsys.readouterr().err
    assert "--set measure.threshold=0.3: an instrument's setting" in err and not out.exists()
    assert main(["measure", "--size", "16", "--set", "measure.heights=poisson"]) == 2
    assert "belongs to phase measuring (--method pmd)" in capsys.readouterr().err
    assert main(["measure", "--size", "16", "--set", "measure.threshold=2"]) == 2
    assert "--set measure.threshold: must be in (0, 1), got 2" in capsys.readouterr().err
