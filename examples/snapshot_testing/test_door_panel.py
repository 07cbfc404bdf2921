"""Snapshot tests of an inspection scene: the image of the door panel and its dent's
visibility, against the baselines in glshade_snapshots/ (pytest --glshade-update writes
them; docs/snapshot-testing.md)."""

from pathlib import Path

import pytest

import glshade

HERE = Path(__file__).parent


def test_door_panel(glshade_snapshot):
    scene = glshade.Scene.load(HERE / "door_panel.toml")
    glshade_snapshot.check(scene, name="door_panel_theta30")


@pytest.mark.glshade_tolerance(visibility_px=0.05)  # this test's own tolerance
@pytest.mark.parametrize("theta", [45.0, 60.0])
def test_door_panel_from_elsewhere(glshade_snapshot, theta):
    scene = glshade.Scene.load(HERE / "door_panel.toml").with_value("camera.theta_deg", theta)
    glshade_snapshot.check(scene, name=f"door_panel_theta{theta:g}")
