"""Scene model: defaults, TOML round trip, validation messages."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from glshade.errors import SceneError
from glshade.scene import (
    Camera,
    Defect,
    Emitter,
    RenderSettings,
    Scene,
    Surface,
    paper_scene,
)


def test_paper_scene_matches_the_paper():
    s = paper_scene("flat", 45.0, 4.0, 0.005)
    assert (s.camera.distance, s.camera.focal, s.camera.pixel_pitch) == (175.6, 25.0, 0.005)
    assert (s.camera.width, s.camera.height) == (1024, 1024)
    assert s.emitter.distance == 256.0 and s.emitter.period == 2.0
    assert paper_scene("sphere").emitter.period == 10.0
    assert paper_scene("cylinder").surface.radius == 70.0
    # FWHM of one stripe = half a period.
    sigma = s.emitter.sigma_mm
    assert math.isclose(2 * math.sqrt(2 * math.log(2)) * sigma, 1.0, rel_tol=1e-12)


def test_geometry_follows_spec():
    s = paper_scene(theta_deg=30.0)
    c = s.camera.world_pose().position
    assert c == pytest.approx(175.6 * __import__("numpy").array([0, 0.5, math.sqrt(3) / 2]))
    forward, right, up = s.camera.basis()
    assert right == pytest.approx([1, 0, 0])
    assert up == pytest.approx([0, math.sqrt(3) / 2, -0.5])
    plane = s.emitter_plane()
    assert plane.centre == pytest.approx(
        256 * __import__("numpy").array([0, 0.5, -math.sqrt(3) / 2])
    )
    assert plane.normal @ plane.e_v == pytest.approx(0.0)
    assert plane.centre @ plane.e_v == pytest.approx(0.0, abs=1e-12)


def test_the_rig_pose_agrees_with_a_look_at_matrix():
    """The camera's pose from the rig (:mod:`glshade.rig`) against pyrr's look-at view
    matrix built from its position alone: its columns hold right, up and -forward."""
    import numpy as np
    import pyrr

    for azimuth in (0.0, 30.0, -120.0):
        cam = Camera(theta_deg=20.0, azimuth_deg=azimuth)
        forward, right, up = cam.basis()
        view = np.asarray(
            pyrr.matrix44.create_look_at(cam.world_pose().position, np.zeros(3), [0, 1, 0])
        )
        np.testing.assert_allclose(view[:3, 0], right, atol=1e-12)
        np.testing.assert_allclose(view[:3, 1], up, atol=1e-12)
        np.testing.assert_allclose(view[:3, 2], -forward, atol=1e-12)
        # the principal point maps to the camera origin, the gazing point onto the axis
        np.testing.assert_allclose(
            np.append(cam.world_pose().position, 1.0) @ view, [0, 0, 0, 1], atol=1e-9
        )
        gaze = (np.array([0.0, 0.0, 0.0, 1.0]) @ view)[:3]
        np.testing.assert_allclose(gaze, [0, 0, -cam.distance], atol=1e-9)


def test_the_orbit_raises_and_turns_the_rig_within_its_range():
    from glshade.rig import ORBIT_THETA_DEG, orbit

    assert orbit(45.0, 0.0, 0.0, -40.0) == (55.0, 0.0)  # dragged up 40 px: 10 deg higher
    assert orbit(45.0, 170.0, 80.0, 0.0) == (45.0, -170.0)  # wraps into (-180, 180]
    assert orbit(45.0, -170.0, -40.0, 0.0) == (45.0, 180.0)
    assert orbit(5.0, 0.0, 0.0, 1000.0)[0] == ORBIT_THETA_DEG[0]
    assert orbit(85.0, 0.0, 0.0, -1000.0)[0] == ORBIT_THETA_DEG[1]


def test_resampling_keeps_field_of_view():
    cam = Camera().resampled(256)
    assert (cam.width, cam.height, cam.pixel_pitch) == (256, 256, 0.02)
    wide = Camera(width=1000, height=500).resampled(100)
    assert (wide.width, wide.height) == (100, 50)
    assert wide.width * wide.pixel_pitch == pytest.approx(1000 * 0.005)


@pytest.mark.parametrize(
    "scene",
    [
        paper_scene("sphere", 5.0, 9.0, 0.003, phase=0.25),
        Scene(
            camera=Camera(theta_deg=12.5, width=320, height=200),
            emitter=Emitter(stripe_sigma=0.3, half_size=(100.0, 80.0)),
            surface=Surface(kind="cylinder", radius=-35.0, axis="x"),
            defect=Defect(dmax=-0.002, sigma_x2=4.0, sigma_z2=1.0, sigma_xz=0.5, x0=1.5, z0=-2.0),
            render=RenderSettings(
                precision="fp64", supersample=3, reflection="blinn-phong", shininess=5e5
            ),
        ),
    ],
)
def test_toml_round_trip(scene, tmp_path):
    path = tmp_path / "scene.toml"
    scene.save(path)
    assert Scene.load(path) == scene
    assert Scene.from_dict(scene.to_dict()) == scene


def test_toml_file_layout_of_spec(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(
        "[camera]\ntheta_deg = 15.0\nwidth = 64\nheight = 64\n"
        '[surface]\nkind = "sphere"\nradius = -70.0\n'
        "[defect]\nsigma_x2 = 4.0\nsigma_z2 = 1.0\nsigma_xz = 0.5\n"
    )
    s = Scene.load(path)
    assert s.camera.theta_deg == 15.0 and s.camera.distance == 175.6
    assert s.surface.concave
    assert not s.defect.isotropic and s.defect.dmax == 0.005
    assert s.to_dict()["defect"]["sigma_xz"] == 0.5


def test_isotropic_written_as_sigma2():
    d = paper_scene(sigma2=9.0).to_dict()["defect"]
    assert d["sigma2"] == 9.0 and "sigma_x2" not in d


@pytest.mark.parametrize(
    "data, field, allowed",
    [
        ({"camera": {"theta_deg": 90.0}}, "camera.theta_deg", "(0.001, 90)"),
        ({"camera": {"theta_deg": 0.0}}, "camera.theta_deg", "(0.001, 90)"),
        ({"camera": {"theta_deg": float("nan")}}, "camera.theta_deg", "finite"),
        ({"camera": {"distance": -1.0}}, "camera.distance", "> 0"),
        ({"camera": {"focal": 0.0}}, "camera.focal", "> 0"),
        ({"camera": {"pixel_pitch": float("inf")}}, "camera.pixel_pitch", "finite"),
        ({"camera": {"width": 0}}, "camera.width", "[1, 16384]"),
        ({"camera": {"height": 2.5}}, "camera.height", "integer"),
        ({"camera": {"width": True}}, "camera.width", "integer"),
        ({"emitter": {"period": 0.0}}, "emitter.period", "in (1e-06, 1e+09) mm"),
        ({"emitter": {"stripe_sigma": -0.1}}, "emitter.stripe_sigma", "> 0"),
        ({"emitter": {"half_size": [1.0]}}, "emitter.half_size", "two numbers"),
        ({"emitter": {"distance": "far"}}, "emitter.distance", "finite number"),
        ({"surface": {"kind": "torus"}}, "surface.kind", "flat, cylinder, sphere"),
        ({"surface": {"radius": 0.0}}, "surface.radius", "non-zero"),
        ({"surface": {"axis": "y"}}, "surface.axis", "z, x"),
        (
            {"defect": {"sigma_x2": 1.0, "sigma_z2": 1.0, "sigma_xz": 1.0}},
            "defect.sigma_xz",
            "positive definite",
        ),
        ({"defect": {"sigma2": -4.0}}, "defect.sigma2", "in (1e-06, 1e+08)"),
        ({"defect": {"sigma2": 4.0, "sigma_xz": 0.1}}, "defect.sigma_xz", "absent"),
        ({"defect": {"dmax": float("nan")}}, "defect.dmax", "finite"),
        ({"render": {"precision": "fp16"}}, "render.precision", "fp32, fp64"),
        ({"render": {"supersample": 0}}, "render.supersample", "[1, 16]"),
        ({"render": {"reflection": "lambert"}}, "render.reflection", "mirror, blinn-phong"),
        ({"render": {"shininess": 0.0}}, "render.shininess", "> 0"),
        ({"camera": {"zoom": 2.0}}, "camera.zoom", "unknown key"),
        ({"lens": {}}, "lens", "unknown table"),
    ],
)
def test_validation_names_field_and_range(data, field, allowed):
    with pytest.raises(SceneError) as info:
        Scene.from_dict(data)
    assert info.value.field == field
    assert allowed in str(info.value)
    assert str(info.value).startswith(field)


def test_bad_toml_is_a_scene_error(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[camera\n")
    with pytest.raises(SceneError, match="valid TOML"):
        Scene.load(path)
    with pytest.raises(SceneError, match="existing TOML file"):
        Scene.load(tmp_path / "missing.toml")


def test_variants():
    s = paper_scene()
    assert s.without_defect().defect.dmax == 0.0 and not s.without_defect().defect.present
    assert s.with_phase(0.75).emitter.phase == 0.75
    assert s.updated(defect={"sigma2": 16.0}).defect.sigma_z2 == 16.0
    aniso = s.updated(defect={"sigma_z2": 1.0})  # one component of an isotropic defect
    assert (aniso.defect.sigma_x2, aniso.defect.sigma_z2, aniso.defect.sigma_xz) == (4.0, 1.0, 0.0)
    assert replace(s.defect, sigma_xz=0.1).isotropic is False
    with pytest.raises(SceneError):
        s.updated(lens={"f": 1})
