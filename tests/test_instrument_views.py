"""The viewer's instrument views come from the registry: every instrument's
:meth:`~glshade.instruments.base.Instrument.views`, measured through the instrument, with
no instrument known to the viewer by name. A fake instrument offering one view is shown
and measured without a window (and without GL); glshade's own offer the views they did."""

from __future__ import annotations

import dataclasses
import warnings
from typing import Any, ClassVar

import numpy as np
import pytest

from glshade.app.viewer import STRIPE_VIEWS, ViewerModel, views
from glshade.app.viewer.colourbar import NO_VALUE_RGB, colour_index, colour_lut
from glshade.app.viewer.instrument_view import instrument_views
from glshade.errors import GlshadeError, GlshadeWarning
from glshade.instruments.base import Instrument, InstrumentView, InstrumentViews, ViewMap
from glshade.instruments.record import Measurement
from glshade.instruments.registry import Instruments, instrument, instruments
from glshade.scene import Scene, paper_scene


@dataclasses.dataclass(frozen=True)
class _Settings:
    gain: float = 2.0


@dataclasses.dataclass(frozen=True)
class _Lit:
    """The fake's result: a level per pixel of the case it measured."""

    level: np.ndarray
    width: int


def _level_map(scene: Scene, result: _Lit) -> ViewMap:
    return ViewMap(result.level, 0.0, float(np.nanmax(result.level)), "lx", "level", "magma")


def _readout(scene: Scene | None, result: _Lit | None, missing: str) -> list[str]:
    shown = missing if result is None else f"{np.nanmean(result.level):.3f} lx"
    return [f"mean level: {shown}", "status: " + ("ok" if result is not None else missing)]


class _Lamp(Instrument):
    """A fake instrument: its result is a ramp of the case's size, scaled by its setting;
    it refuses a scene whose camera looks from below 10 degrees."""

    name: ClassVar[str] = "lamp"
    title: ClassVar[str] = "a lamp"
    settings_type: ClassVar[type] = _Settings
    record_type = Measurement
    outputs: ClassVar[tuple[str, ...]] = ("visibility_px", "status")

    def __init__(self) -> None:
        self.calls: list[tuple[Any, Scene, Any]] = []

    def prepared(self, scene: Scene) -> Scene:
        return scene

    def measure(self, renderer: Any, scene: Scene, settings: Any) -> _Lit:
        self.calls.append((renderer, scene, settings))
        if scene.camera.theta_deg < 10.0:
            raise GlshadeError("lamp: the camera is too low")
        width = scene.camera.width
        level = settings.gain * np.arange(width * width, dtype=np.float64).reshape(width, width)
        level[0, 0] = np.nan  # no value there
        return _Lit(level, width)

    def record(self, scene: Any, result: Any, trace_s: float = 0.0) -> Any:
        raise NotImplementedError

    def views(self) -> InstrumentViews:
        return InstrumentViews("Lamp", (InstrumentView("lamp-level", "level", _level_map),),
                               _readout, size=16)  # fmt: skip


class _NoRenderer:
    """What the fake's station measures with (a fake's measure needs no GL)."""


def _model(found: Instruments, view: str = "lamp-level", size: int = 32) -> ViewerModel:
    scene = paper_scene().with_size(size)
    model = ViewerModel(scene, view=view, instruments=found, make_renderer=_NoRenderer)
    uv = np.zeros((size, size, 2), np.float32)  # as if traced: the image's size
    model.uv1, model.v1 = uv, uv[..., 1]
    return model


def test_a_view_offered_by_a_fake_instrument_is_shown_and_measured_through_it():
    lamp = _Lamp()
    found = Instruments({"paper": instrument("paper"), "lamp": lamp})
    assert views(found) == (*STRIPE_VIEWS, "lamp-level")
    model = _model(found)
    assert model.view_names() == (*STRIPE_VIEWS, "lamp-level")
    assert [o.view.name for o in model.first_views()] == ["lamp-level"]
    # before the case: a dark picture captioned by the instrument, "..." for its numbers
    rgba, scale = model.instrument_rgba()
    assert not rgba[..., :3].any() and scale.caption == "a lamp: computing..."
    model.start_metrics()
    assert model.readout_text() == ["mean level: ...", "status: ...", "Lamp at 16 px: computing..."]
    model.wait_for_metrics()
    # measured once, through the instrument, on its scene at its size, with its settings
    (renderer, scene, settings), = lamp.calls  # fmt: skip
    assert isinstance(renderer, _NoRenderer) and settings == _Settings()
    assert scene == model.scene.with_phase(0.0).with_size(16) and model.cases.last.scene == scene
    result = model.cases.last.result
    assert isinstance(result, _Lit) and result.width == 16
    # the map: the fake's values on its scale, at the image's size, grey where none
    rgba, scale = model.instrument_rgba()
    top = float(np.nanmax(result.level))
    assert (scale.bottom, scale.top, scale.unit, scale.cmap) == (0.0, top, "lx", "magma")
    assert scale.caption == "level, grey: none"
    assert rgba.shape == (32, 32, 4)
    lut = colour_lut("magma")
    expected = lut[colour_index(result.level[5, 7], top)]
    assert (rgba[10, 14, :3] == expected).all() and (rgba[11, 15, :3] == expected).all()
    assert (rgba[:2, :2, :3] == NO_VALUE_RGB).all()
    # the hover: the view's label, its value and unit at the case's pixel
    assert model.hover(14, 10) == f"pixel (14, 10): level {result.level[5, 7]:.4g} lx"
    assert model.hover(0, 1) == "pixel (0, 1): level: no value"
    mean = f"{np.nanmean(result.level):.3f} lx"
    seconds = f"{model.cases.last.seconds:.2f} s"
    assert model.readout_text() == [
        f"mean level: {mean}",
        "status: ok",
        f"Lamp at 16 px: {seconds}",
    ]
    # no change, no case; a change of the stripes' phase is none either
    model.set("phase", 0.3)
    model.start_metrics()
    assert model.cases.job is None and len(lamp.calls) == 1
    # a scene the instrument refuses: its reason, "-" for its numbers, nothing retried
    model.set("theta", 5.0)
    model.settle_metrics()
    assert (
        model.cases.last.result is None and model.cases.last.error == "lamp: the camera is too low"
    )
    assert model.readout_text() == [
        "mean level: -", "status: -", "Lamp at 16 px: 0.00 s",
        "not measured: lamp: the camera is too low",
    ]  # fmt: skip
    assert model.instrument_rgba()[1].caption == "a lamp: not measured (see the readout)"
    model.start_metrics()
    assert model.cases.job is None and len(lamp.calls) == 2
    # the P key: the image, then the instrument's first view again
    model.toggle_instrument_view()
    assert model.view == "image" and model.instrument_view is None
    model.toggle_instrument_view()
    assert model.view == "lamp-level"
    model.close()


def test_an_instrument_without_views_offers_none_and_a_broken_offer_is_left_out():
    class Broken(_Lamp):
        name: ClassVar[str] = "broken"

        def views(self) -> InstrumentViews:
            raise RuntimeError("no views today")

    class Twice(_Lamp):
        name: ClassVar[str] = "twice"  # offers a view another instrument offers already

    found = Instruments({"paper": instrument("paper"), "lamp": _Lamp(), "broken": Broken(),
                         "twice": Twice()})  # fmt: skip
    assert instrument("paper").views() is None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        offered = instrument_views(found)
    assert list(offered) == ["lamp-level"] and offered["lamp-level"].instrument.name == "lamp"
    words = sorted(str(w.message) for w in caught if issubclass(w.category, GlshadeWarning))
    assert words == [
        "instrument 'broken': views left out: RuntimeError: no views today",
        "instrument 'twice': views left out: view 'lamp-level' is offered twice",
    ]
    model = _model(Instruments({"paper": instrument("paper")}), view="image")
    assert model.view_names() == STRIPE_VIEWS and model.first_views() == []
    model.toggle_instrument_view()  # no instrument view: P does nothing
    assert model.view == "image"
    with pytest.raises(GlshadeError, match="not an instrument's"):
        model.instrument_rgba()


def test_glshade_offers_the_views_it_always_did():
    """The same view names in the same order: the viewer's own, then phase measuring's."""
    assert list(instruments().by_name) == ["paper", "pmd"]
    assert views() == (
        "image", "defect-free", "overlay", "displacement",
        "pmd-phase", "pmd-modulation", "pmd-error", "pmd-slope",
    )  # fmt: skip
    offer = instrument("pmd").views()
    assert offer is not None and offer.label == "PMD" and offer.size == 256
    assert [v.label for v in offer.views] == ["phase", "modulation", "error", "slope"]


def test_a_scene_files_measure_table_sets_the_views_settings():
    """``glshade view`` of a file with ``[measure]``: an instrument view is measured with
    the table's settings where the table is that instrument's, else with its defaults;
    the stripe views take the table where it is the stripe metric's."""
    from glshade.instruments.table import MeasureTable

    for table, gain in ((MeasureTable("lamp", True, {"gain": 3.0}), 3.0),
                        (MeasureTable("paper", True, {"threshold": 0.7}), 2.0)):  # fmt: skip
        lamp = _Lamp()
        found = Instruments({"paper": instrument("paper"), "lamp": lamp})
        model = ViewerModel(paper_scene().with_size(32), view="lamp-level", instruments=found,
                            make_renderer=_NoRenderer, measure_table=table)  # fmt: skip
        size = 32
        uv = np.zeros((size, size, 2), np.float32)
        model.uv1, model.v1 = uv, uv[..., 1]
        model.start_metrics()
        model.wait_for_metrics()
        (_, _, settings), = lamp.calls  # fmt: skip
        assert settings == _Settings(gain=gain)
        assert model.settings.threshold == (0.7 if table.method == "paper" else 0.5)
        model.close()
