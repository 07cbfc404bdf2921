"""What ``glshade measure --method pmd`` writes and reports, checked against what it claims:
the numbers recomputed from the ``--maps`` files, a ``--frames`` folder decoded with its
manifest alone, one direction order (u, v) everywhere, the modulation as an optical share
of at most 1, one answer for a scene without a dent, and a frames folder that holds
exactly its manifest's frames."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from glshade.app.cli import main
from glshade.instruments.pmd import decode as pmd
from glshade.instruments.pmd.files import DATA_FILES, MAP_FILES, write_frames, write_maps
from glshade.instruments.pmd.station import measure_pmd_scene
from glshade.instruments.pmd.status import pmd_concerns
from glshade.instruments.record import PmdMeasurement
from glshade.instruments.stripes.single import measure_scene
from glshade.metrics.coding_laws import screen_harmonics
from glshade.scene import Scene, paper_scene

SENSOR = ["--full-well", "10000"]
NO_DENT = "the scene has no dent (defect.dmax = 0)"


def station(surface: str = "flat", theta: float = 45.0, size: int = 48, **emitter) -> Scene:
    """The paper's dent (σ² 4 mm², 5 µm) under a PMD station of the default coding."""
    scene = paper_scene(surface, theta_deg=theta, sigma2=4.0, dmax=0.005).with_size(size)
    return scene.updated(emitter={"kind": "fringes", **emitter})


def run(capsys, *args: str) -> dict:
    """``glshade measure --method pmd --json ARGS``: its record."""
    assert main(["measure", "--method", "pmd", "--json", *args]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.fixture(scope="module")
def written(_session_renderer, tmp_path_factory):
    """One case through a 10 000 e- sensor at 64 px: its record (as ``--json`` prints it),
    its maps and its 16-bit frames, written as ``--maps`` and ``--frames`` write them."""
    folder = tmp_path_factory.mktemp("pmd")
    maps, frames = folder / "maps", folder / "frames"
    scene = station(size=64).updated(sensor={"full_well_e": 10000.0})
    result = measure_pmd_scene(_session_renderer, scene, keep_frames=True)
    write_maps(maps, scene, result)
    write_frames(frames, scene, result)
    return PmdMeasurement.of(scene, result).outputs(), maps, frames


# --------------------------------------------------------------------------- --maps
def test_the_maps_recompute_the_shift_and_the_noise(written):
    """``pmd_shift_mm``, ``pmd_noise_mm`` and its floor, ``modulation`` and the error map
    from the written files alone, to the record's rounding."""
    record, maps, _ = written
    names = {p.name for p in maps.iterdir()}
    assert names >= {f"{n}.npy" for n in (*MAP_FILES, *DATA_FILES)}
    load = {n: np.load(maps / f"{n}.npy") for n in (*MAP_FILES, *DATA_FILES)}
    decoded, base, twin = load["decoded"], load["decoded_defect_free"], load["decoded_twin"]
    assert decoded.dtype == base.dtype == np.float64 and decoded.shape == (64, 64, 2)
    shift = np.linalg.norm(decoded - base, axis=-1)[load["shift_pixels"]]
    assert shift.size > 20
    assert shift.max() == pytest.approx(record["pmd_shift_mm"], abs=1e-6)
    diff = (base - twin)[load["noise_pixels"]]
    assert diff.size > 200 and np.isfinite(diff).all()
    assert np.std(diff) / math.sqrt(2.0) == pytest.approx(record["pmd_noise_mm"], abs=1e-7)
    assert np.abs(diff).max() == pytest.approx(record["pmd_noise_floor_mm"], abs=1e-6)
    share = load["modulation_share"][:, load["region"]]
    assert np.median(share) == pytest.approx(record["modulation"], abs=1e-4)
    np.testing.assert_array_equal(load["error_mm"], decoded - load["exact"])
    # the twin is another recording: its decode differs, by noise only
    assert 0 < np.nanmax(np.abs(base - twin)) < 0.1
    assert np.isfinite(load["exact_defect_free"]).mean() > 0.9


# --------------------------------------------------------------------------- --frames
def decode_folder(folder: Path) -> np.ndarray:
    """A ``--frames`` folder decoded with nothing but its manifest and the files it names
    (OpenCV reads them; :func:`glshade.instruments.pmd.decode.decode` decodes): the screen points
    (H, W, 2: u, v in mm, NaN where not valid or not coded)."""
    manifest = json.loads((folder / "manifest.json").read_text())
    scale = 65535.0 if manifest["format"].startswith("16-bit") else 1.0
    black = manifest["sensor_black_level"]

    def read(name: str) -> np.ndarray:  # above the black level, recorded units
        image = cv2.imread(str(folder / name), cv2.IMREAD_UNCHANGED)
        return image.astype(np.float64) / scale - black

    coding, white, rule = manifest["coding"], manifest["white"], manifest["validity"]
    response = read(white["file"])
    # the white file holds the response the threshold is based on (within its noise)
    assert np.percentile(response, 99.9) == pytest.approx(white["response"], rel=0.05)
    threshold = rule["modulation_share"] * coding["amplitude"] * white["response"]
    assert threshold == pytest.approx(rule["min_modulation"], rel=1e-12)
    periods, shifts = coding["periods_mm"], coding["shifts"]
    out = np.full((*response.shape, 2), np.nan)
    for direction in coding["directions"]:
        mine = [f for f in manifest["frames"] if f["direction"] == direction]
        mine.sort(key=lambda f: (f["period_index"], f["shift_index"]))
        for f in mine:
            assert f["shift_rad"] == pytest.approx(2 * math.pi * f["shift_index"] / shifts)
            assert f["period_mm"] == periods[f["period_index"]]
        stack = np.stack([read(f["file"]) for f in mine])
        stack = stack.reshape(len(periods), shifts, *response.shape)
        axis = "uv".index(direction)
        half = coding["screen_half_size_mm"][axis]
        code = pmd.FringeCodec.from_dict(coding)
        decoded = pmd.decode(stack, code, min_modulation=threshold, direction=direction)
        out[..., axis] = decoded.s_mm - half
    return out


def test_a_frames_folder_decodes_with_its_manifest_alone(written):
    record, maps, frames = written
    manifest = json.loads((frames / "manifest.json").read_text())
    assert manifest["exposure"]["camera_exposure"] == "auto"
    assert 0.5 < manifest["exposure"]["gain"] < 2.0  # the gain applied, as a number
    assert manifest["sensor"]["black_level_dn"] == 64
    assert manifest["sensor_black_level"] == manifest["sensor"]["black_level"] == 64 / 4095
    # the coding is the scene's codec, written from its own dict: it reads back as that codec
    codec = Scene.from_dict(manifest["scene"]).emitter.codec
    assert manifest["coding"] == codec.to_dict()
    assert pmd.FringeCodec.from_dict(manifest["coding"]) == codec
    mine = decode_folder(frames)
    theirs = np.load(maps / "decoded.npy")
    both = np.isfinite(mine) & np.isfinite(theirs)
    assert both.mean() > 0.9
    assert (np.isfinite(mine) == np.isfinite(theirs)).mean() > 0.999
    assert np.abs(mine - theirs)[both].max() < 1e-3  # 16-bit rounding of the frames
    assert record["status"] == "ok"


def test_tiff_frames_of_one_direction_decode_exactly(tmp_path, capsys):
    """Float TIFF frames hold the recorded values themselves: the decode is the
    measurement's, here of a sequence coding u alone (its v layer NaN)."""
    frames, maps = tmp_path / "frames", tmp_path / "maps"
    args = ["--size", "32", *SENSOR, "--set", "emitter.directions=u", "--frame-format", "tif"]
    run(capsys, *args, "--frames", str(frames), "--maps", str(maps))
    mine, theirs = decode_folder(frames), np.load(maps / "decoded.npy")
    assert np.isnan(mine[..., 1]).all() and np.isnan(theirs[..., 1]).all()
    np.testing.assert_allclose(mine, theirs, atol=1e-9)  # NaN where NaN
    assert np.isfinite(theirs[..., 0]).mean() > 0.9


# --------------------------------------------------------------------------- (u, v)
def test_every_per_direction_axis_is_u_then_v(renderer, tmp_path):
    """The default sequence shows v then u; its per-direction maps are (u, v): layer 0
    is what a sequence of u alone decodes, layer 1 what one of v alone decodes; a
    direction not coded is NaN, and so is every pixel that sees no screen (the sphere at
    θ 10° sees it with a fifth of its pixels)."""
    scene = station("sphere", 10.0, size=32)
    result = measure_pmd_scene(renderer, scene)
    both = result.maps
    only = {d: measure_pmd_scene(renderer, scene.updated(emitter={"directions": [d]})).maps
            for d in ("u", "v")}  # fmt: skip
    for axis, direction in enumerate("uv"):
        for name in ("modulation", "wrapped", "modulation_share"):
            np.testing.assert_array_equal(
                getattr(both, name)[axis], getattr(only[direction], name)[axis]
            )
            assert np.isnan(getattr(only[direction], name)[1 - axis]).all()
    seen = np.isfinite(both.exact).all(axis=-1)
    assert 0.05 < seen.mean() < 0.5
    for per_direction in (both.modulation[:, 0], both.wrapped[:, 0], both.modulation_share):
        assert np.isnan(per_direction[:, ~seen]).all()
        assert np.isfinite(per_direction[:, seen]).all()
    write_maps(tmp_path, scene, result)
    assert np.load(tmp_path / "modulation.npy").shape == (2, 4, 32, 32)
    assert np.isnan(np.load(tmp_path / "wrapped_phase.npy")[:, :, ~seen]).all()


# --------------------------------------------------------------------------- modulation
def test_the_modulation_is_an_optical_share_of_at_most_one(renderer):
    """A sharp mirror keeps the displayed fringe: each pixel's share is 1 within the
    screen's 256 grey levels' bound (their phasor errs by at most one step ``q``, so
    ``|B - b1| <= q``), the record's number 1 within it; the sphere at θ 10° without a
    dent (most pixels see no screen) reads the same over its seen pixels; a sensor
    leaves it unchanged (it is the radiance's), and so does the screen's own black level
    and room light."""
    q = 1.0 / 255.0
    bound = q / screen_harmonics(station().emitter)[1]
    for scene in (station(), station("sphere", 10.0).updated(defect={"dmax": 0.0})):
        result = measure_pmd_scene(renderer, scene)
        share = result.maps.modulation_share
        finite = share[np.isfinite(share)]
        assert finite.size > 200
        assert np.abs(finite - 1.0).max() <= bound
        assert abs(result.modulation - 1.0) <= bound and result.modulation <= 1.0 + 1e-3
    noisy = measure_pmd_scene(renderer, station().updated(sensor={"full_well_e": 10000.0}))
    assert noisy.modulation == measure_pmd_scene(renderer, station()).modulation
    # a continuous screen with a black level and room light: the share is the optics',
    # the screen's own white and fringe divided out (1 to float32 rounding)
    lit = measure_pmd_scene(renderer, station(levels=0, black_level=0.05, ambient=0.1))
    share = lit.maps.modulation_share[np.isfinite(lit.maps.modulation_share)]
    assert np.abs(share - 1.0).max() < 1e-4


# --------------------------------------------------------------------------- no dent
@pytest.mark.parametrize(
    ("surface", "theta", "sensor"),
    [("flat", 45.0, None), ("flat", 45.0, 10000.0), ("sphere", 10.0, None)],
)
def test_a_scene_without_a_dent_has_one_answer(renderer, surface, theta, sensor):
    """``outside`` with one reason from both instruments, whatever the surface and the
    sensor; the dent's numbers unreadable, the station's own readable."""
    scene = station(surface, theta).updated(defect={"dmax": 0.0})
    scene = scene.updated(sensor={"full_well_e": sensor}) if sensor else scene
    result = measure_pmd_scene(renderer, scene)
    assert result.status == "outside" and result.status_reason.startswith(NO_DENT)
    for column in ("pmd_shift_mm", "pmd_snr", "pmd_depth_um", "pmd_sigma_mm"):
        assert pmd_concerns(result.status, column)
    for column in ("pmd_noise_mm", "decode_rms_mm", "valid_fraction", "modulation"):
        assert not pmd_concerns(result.status, column)
    assert result.valid_fraction == 1.0 and math.isfinite(result.modulation)
    assert (result.pmd_noise_mm > 0) == (sensor is not None)
    stripes = paper_scene(surface, theta_deg=theta, dmax=0.0).with_size(64)
    stripes = stripes.updated(sensor={"full_well_e": sensor}) if sensor else stripes
    paper = measure_scene(renderer, stripes)
    assert (paper.status, paper.status_reason) == (result.status, result.status_reason)


# --------------------------------------------------------------------------- the folder
def test_a_frames_folder_holds_exactly_its_manifests_frames(tmp_path, capsys):
    frames = tmp_path / "frames"
    run(capsys, "--size", "16", "--set", "emitter.shifts=6", "--frames", str(frames))
    assert len(list(frames.glob("frame_*.png"))) == 2 * 4 * 6 + 1
    (frames / "notes.txt").write_text("mine")
    (frames / "frame_notes.png").write_text("not a name glshade gives")
    (frames / "frame_999_u_p0_n0.tif").write_text("an earlier run's")
    run(capsys, "--size", "16", "--set", "emitter.directions=u", "--frames", str(frames))
    manifest = json.loads((frames / "manifest.json").read_text())
    named = {f["file"] for f in manifest["frames"]} | {manifest["white"]["file"]}
    assert len(named) == 4 * 4 + 1
    kept = {"manifest.json", "notes.txt", "frame_notes.png"}
    assert {p.name for p in frames.iterdir()} == named | kept


def test_a_link_among_the_frames_is_refused_before_any_work(tmp_path, capsys):
    frames, elsewhere = tmp_path / "frames", tmp_path / "elsewhere.png"
    frames.mkdir()
    elsewhere.write_text("keep me")
    (frames / "kept.png").write_text("inside")
    (frames / "frame_040_u_p0_n0.png").symlink_to(frames / "kept.png")
    code = main(["measure", "--method", "pmd", "--size", "16", "--frames", str(frames)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.count("\n") == 0 and "frame_040_u_p0_n0.png" in err, err
    assert "symbolic link" in err
    assert sorted(p.name for p in frames.iterdir()) == ["frame_040_u_p0_n0.png", "kept.png"]
    assert elsewhere.read_text() == "keep me"
