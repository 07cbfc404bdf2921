"""An instrument's setting is a sweep axis like a scene key: ``"measure.threshold" =
[0.3, 0.6]`` measures each case with that setting (its own case id), the table has the
setting's column, and a value out of the setting's declared range, or a key that is not
a setting of the sweep's instrument, is one line."""

from __future__ import annotations

import csv

import pytest

import glshade
from glshade.app.cli import main
from glshade.errors import GlshadeError
from glshade.instruments.record import Measurement
from glshade.metrics.visibility import MetricSettings
from glshade.sweep.spec import spec_from_dict

GRID = {"camera.theta_deg": [45.0], "measure.threshold": [0.3, 0.6]}


def test_each_case_is_measured_with_its_setting(tmp_path, renderer):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(
        'size = 48\n[grid]\n"camera.theta_deg" = [45.0]\n"measure.threshold" = [0.3, 0.6]\n'
    )
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "out"), "--no-progress"]) == 0
    with open(tmp_path / "out" / "results.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [float(row["measure.threshold"]) for row in rows] == [0.3, 0.6]
    spec = spec_from_dict({"size": 48, "grid": GRID})
    for row, case in zip(rows, spec.cases(), strict=True):
        settings = MetricSettings(threshold=float(row["measure.threshold"]))
        alone = glshade.measure(case.scene, renderer=renderer, settings=settings)
        expected = Measurement.of(case.scene, alone).outputs()
        assert {key: row[key] for key in ("status", "folded")} == {
            "status": expected["status"],
            "folded": str(expected["folded"]),
        }
        assert float(row["visibility_px"]) == expected["visibility_px"]
        assert float(row["deflection_px"]) == pytest.approx(expected["deflection_px"])


def test_the_setting_changes_the_case_id_and_only_the_settings():
    spec = spec_from_dict({"size": 48, "grid": GRID})
    first, second = spec.cases()
    assert first.scene == second.scene and first.case_id != second.case_id
    assert (first.settings.threshold, second.settings.threshold) == (0.3, 0.6)
    plain = spec_from_dict({"size": 48, "grid": {"camera.theta_deg": [45.0]}})
    fixed = spec_from_dict({"size": 48, "grid": {"camera.theta_deg": [45.0]},
                            "measure": {"threshold": 0.3}})  # fmt: skip
    assert fixed.cases()[0].case_id == first.case_id != plain.cases()[0].case_id


@pytest.mark.parametrize(
    "axis, words",
    [
        ({"measure.threshold": [2.0]}, "grid.measure.threshold: must be in (0, 1), got 2.0"),
        ({"measure.heights": ["poisson"]}, "grid.measure.heights: not a setting of this sweep"),
        ({"measure.step_mm": [50.0]}, "step: must be at most one stripe period"),
    ],
)
def test_a_bad_setting_axis_is_one_line(axis, words):
    with pytest.raises(GlshadeError) as info:
        spec_from_dict({"size": 48, "grid": {"camera.theta_deg": [45.0], **axis}})
    assert words in str(info.value) and "\n" not in str(info.value)
