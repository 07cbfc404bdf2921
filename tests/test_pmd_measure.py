"""Phase measuring, end to end on rendered scenes: the decoded map against the exact map the
renderer traced, the measured noise against its prediction over several seeds, a screen
gamma's harmonic error against its Fourier prediction, the reconstructed dent against the
true one (flat plate, a height map), the statuses, the files for external decoders, the
Python call and the command line's refusals."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import glshade
from glshade.app.cli import main
from glshade.files import read_png
from glshade.instruments.pmd import decode as pmd
from glshade.instruments.pmd.baseline import pmd_baseline
from glshade.instruments.pmd.model import station_model
from glshade.instruments.pmd.settings import PmdSettings
from glshade.instruments.pmd.station import PmdResult, measure_pmd_scene
from glshade.metrics import physics
from glshade.scene import Scene, paper_scene

SENSOR = {"full_well_e": 10000.0, "read_noise_e": 5.0, "bit_depth": 12}


def station(surface: str = "flat", theta: float = 45.0, size: int = 128, **emitter) -> Scene:
    """The paper's dent (σ² 4 mm², 5 µm) seen by a PMD station of the default coding."""
    scene = paper_scene(surface, theta_deg=theta, sigma2=4.0, dmax=0.005).with_size(size)
    return scene.updated(emitter={"kind": "fringes", **emitter})


# --------------------------------------------------------------------------- decoding
@pytest.mark.parametrize(
    ("surface", "theta"),
    [("flat", 45.0), ("flat", 15.0), ("cylinder", 45.0), ("sphere", 25.0), ("sphere", 85.0)],
)
def test_the_decoded_map_is_the_exact_map_without_noise(renderer, surface, theta):
    result = measure_pmd_scene(renderer, station(surface, theta, size=96))
    # point-sampled pixels, 256 grey levels: the decode errs by the levels' rounding only
    # (the bound of docs/pmd.md: p1 / 2π · asin(q / B) = 2.5 µm), far below the 2 mm fringe
    assert result.decode_rms_mm < 2.5e-3
    assert result.unwrap_failures == 0
    assert result.valid_fraction == 1.0
    error = result.maps.error[np.isfinite(result.maps.error)]
    assert np.abs(error).max() < 0.5 * 2.0 / 100  # everywhere, not only on average


def test_the_decoded_maps_of_both_directions_are_the_traced_u_and_v(renderer):
    result = measure_pmd_scene(renderer, station(size=64, directions=["u"]))
    decoded, exact = result.maps.decoded, result.maps.exact
    assert np.isnan(decoded[..., 1]).all()  # v is not coded
    seen = np.isfinite(decoded[..., 0])
    assert seen.mean() > 0.9
    assert np.abs(decoded[..., 0] - exact[..., 0])[seen].max() < 0.01


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_the_measured_noise_is_the_predicted_noise(renderer, seed):
    scene = station(size=96).updated(sensor={**SENSOR, "seed": seed})
    result = measure_pmd_scene(renderer, scene)
    assert result.pmd_noise_mm > 0
    assert result.pmd_noise_mm == pytest.approx(result.pmd_noise_predicted_mm, rel=0.15)
    assert result.pmd_snr == pytest.approx(result.pmd_shift_mm / result.pmd_noise_mm)
    assert result.status == "ok"


def gamma_error_rad(shifts: int, gamma: float) -> float:
    """The phase error's amplitude a screen gamma gives ``N`` steps: ``|b_(N+1) - b_(N-1)|
    / b_1`` of the displayed fringe's Fourier coefficients (docs/pmd.md)."""
    theta = np.linspace(0.0, 2.0 * np.pi, 4096, endpoint=False)
    fringe = (0.5 + 0.5 * np.cos(theta)) ** gamma
    b = 2.0 * np.abs(np.fft.rfft(fringe)) / theta.size
    return abs(b[shifts + 1] - b[shifts - 1]) / b[1]


def test_a_screen_gamma_aliases_as_theory_says(renderer):
    """Rendered, not synthetic: the harmonic error of a gamma-2.2 screen with 3, 4 and 8
    steps, whose rms on the screen is ``p1 / 2π`` times the phase error's amplitude over
    sqrt 2, within 20 % (the fringe's phase is sampled by the pixels, not uniformly)."""
    measured = {}
    for shifts in (3, 4, 8):
        scene = station(size=96, gamma=2.2, levels=0, shifts=shifts)
        measured[shifts] = measure_pmd_scene(renderer, scene).decode_rms_mm
    for shifts in (3, 4):
        predicted = 2.0 / (2.0 * np.pi) * gamma_error_rad(shifts, 2.2) / math.sqrt(2.0)
        assert measured[shifts] == pytest.approx(predicted, rel=0.2)
    assert measured[3] > 10 * measured[4] > 10 * measured[8]


# --------------------------------------------------------------------------- the dent
def test_the_papers_dent_is_reconstructed_on_a_flat_plate(renderer):
    scene = station(size=256)
    result = measure_pmd_scene(renderer, scene)
    assert result.status == "ok"
    assert result.pmd_depth_um == pytest.approx(5.0, rel=0.05)
    assert result.pmd_sigma_mm == pytest.approx(2.0, rel=0.05)
    assert result.pmd_shift_mm == pytest.approx(physics.pmd_shift_mm(scene), rel=0.03)
    assert result.pmd_shift_mm == pytest.approx(result.pmd_shift_exact_mm, rel=0.01)
    steepest = 0.005 * math.exp(-0.5) / 2.0  # dmax e^(-1/2) / σ
    assert result.pmd_slope_urad == pytest.approx(1e6 * steepest, rel=0.03)
    # the heights map holds the dent where it is: its lowest point near the image's centre
    height = result.maps.height_um
    row, col = np.unravel_index(np.nanargmin(height), height.shape)
    assert abs(row - 128) < 8 and abs(col - 128) < 8
    assert np.nanmin(height) == pytest.approx(-5.0, rel=0.05)


def test_the_dent_is_reconstructed_through_a_noisy_sensor(renderer):
    scene = station(size=192).updated(sensor=SENSOR)
    result = measure_pmd_scene(renderer, scene)
    assert result.status == "ok" and result.pmd_snr > 50
    assert result.pmd_depth_um == pytest.approx(5.0, rel=0.05)


def test_a_dent_on_a_height_map_surface(renderer, tmp_path):
    """A curved part given as a sampled height map (a gentle trough, 1 / 500 mm⁻¹ across):
    its nominal normals come from the map, and the dent comes back from the slopes."""
    spacing = 0.1
    x = np.arange(-300, 301) * spacing
    heights = np.broadcast_to(-(x[None, :] ** 2) / 1000.0, (601, 601)).copy()
    np.save(tmp_path / "trough.npy", heights)
    scene = station(size=192).updated(
        surface={
            "kind": "heightmap",
            "file": str(tmp_path / "trough.npy"),
            "spacing": (spacing, spacing),
        }
    )
    result = measure_pmd_scene(renderer, scene)
    assert result.status == "ok"
    assert result.unwrap_failures == 0
    assert result.pmd_depth_um == pytest.approx(5.0, rel=0.05)


def test_one_defect_free_analysis_serves_every_dent(renderer):
    scene = station(size=64)
    baseline = pmd_baseline(renderer, station_model(scene), PmdSettings())
    deeper = scene.updated(defect={"dmax": 0.01})
    shared = measure_pmd_scene(renderer, deeper, PmdSettings(), baseline)
    own = measure_pmd_scene(renderer, deeper, PmdSettings())
    assert shared.pmd_shift_mm == own.pmd_shift_mm
    assert shared.pmd_depth_um == own.pmd_depth_um


# --------------------------------------------------------------------------- statuses
def test_a_dent_outside_the_image_is_outside(renderer):
    result = measure_pmd_scene(renderer, station(size=48).updated(defect={"x0": 40.0}))
    assert result.status == "outside"


def test_a_dent_at_the_image_border_is_at_an_edge(renderer):
    result = measure_pmd_scene(renderer, station(size=64).updated(defect={"x0": 17.0}))
    assert result.status == "edge" and "border" in result.status_reason


def test_fringes_finer_than_the_pixels_resolve_are_unresolved(renderer):
    fine = station(size=48, periods=[0.25, 2.0, 16.0, 128.0, 1024.0])
    result = measure_pmd_scene(renderer, fine.updated(render={"supersample": 3}))
    assert result.status == "unresolved"
    assert "0.25 mm fringes" in result.status_reason
    assert result.modulation < 0.3


def test_a_dent_below_the_noise_is_noise(renderer):
    faint = station(size=64).updated(defect={"dmax": 2e-5}, sensor={"full_well_e": 300.0})
    result = measure_pmd_scene(renderer, faint)
    assert result.status == "noise" and "not above" in result.status_reason
    # the decoded shift is noise's own: the dent's true shift is far below it
    assert result.pmd_shift_exact_mm < 0.1 * result.pmd_noise_floor_mm < result.pmd_shift_mm


def test_auto_exposure_puts_the_brightest_fringe_near_full_scale(renderer):
    from glshade.instruments.pmd.capture import capture

    shot = capture(renderer, station(size=48).updated(sensor=SENSOR))
    recorded = shot.recorded()
    assert 0.85 < float(np.percentile(recorded, 99.9)) < 0.97
    # 0.9 of the range above the black level (64 DN of 4095 at 12 bits)
    black = 64 / 4095
    assert shot.black_level == black
    assert shot.peak_response == pytest.approx((1 - black) * 0.9, rel=1e-6)


# --------------------------------------------------------------------------- the API
def test_the_python_call_measures_by_phase_on_request():
    scene = paper_scene().with_size(32)  # stripes: shown as fringes on the same screen
    result = glshade.measure(scene, method="pmd")
    assert isinstance(result, PmdResult)
    assert math.isfinite(result.pmd_shift_mm)
    assert isinstance(glshade.measure(station(size=32)), PmdResult)  # fringes: by default
    with pytest.raises(glshade.GlshadeError, match="method: must be one of paper, pmd"):
        glshade.measure(scene, method="phase")
    with pytest.raises(glshade.GlshadeError, match="overlay: method 'pmd' draws no contour"):
        glshade.measure(station(size=32), overlay="x.png")


# --------------------------------------------------------------------------- files
def test_the_written_frames_decode_like_the_measurement(tmp_path, capsys):
    frames_dir, maps_dir = tmp_path / "frames", tmp_path / "maps"
    args = ["measure", "--method", "pmd", "--size", "48", "--json"]
    assert main([*args, "--frames", str(frames_dir), "--maps", str(maps_dir)]) == 0
    out = json.loads(capsys.readouterr().out)
    manifest = json.loads((frames_dir / "manifest.json").read_text())
    assert len(manifest["frames"]) == 32
    first = manifest["frames"][0]
    assert set(first) >= {"file", "direction", "period_mm", "shift_index", "shift_rad"}
    assert Scene.from_dict(manifest["scene"]).emitter.kind == "fringes"
    stack = np.stack(
        [read_png(frames_dir / f["file"]).astype(np.float64) / 65535.0 for f in manifest["frames"]]
    )
    decoded = np.load(maps_dir / "decoded.npy")
    coding = manifest["coding"]
    code = pmd.FringeCodec.from_dict(coding)
    for d, direction in enumerate(coding["directions"]):
        axis = 0 if direction == "u" else 1
        block = stack[d * 16 : (d + 1) * 16].reshape(4, 4, 48, 48)
        mine = pmd.decode(block, code, direction=direction).s_mm
        mine = mine - coding["screen_half_size_mm"][axis]
        both = np.isfinite(mine) & np.isfinite(decoded[..., axis])
        assert both.mean() > 0.9
        assert np.abs(mine - decoded[..., axis])[both].max() < 0.01  # 16-bit rounding
    for name in ("decoded", "modulation", "wrapped_phase", "error_mm", "slopes", "height_um"):
        assert (maps_dir / f"{name}.npy").is_file() and (maps_dir / f"{name}.png").is_file()
    assert out["status"] in ("ok", "edge", "unresolved")


# --------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--set", "emitter.shifts=2"], ["emitter.shifts", "2"]),
        (["--set", "emitter.periods=2,16,128,256"], ["emitter.periods", "300 mm", "256"]),
        (["--set", "emitter.gamma=0"], ["emitter.gamma", "0"]),
        (["--set", "emitter.levels=1"], ["emitter.levels", "1"]),
        (["--set", "emitter.offset=0.6"], ["emitter.offset", "offset + amplitude <= 1"]),
        (["--set", "emitter.amplitude=0.4", "--set", "emitter.offset=0.3"], ["emitter.amplitude"]),
        (["--step", "0.1"], ["--step", "--method pmd"]),
        (["--modulation-share", "1.5"], ["--modulation-share", "1.5"]),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, args, words):
    maps = tmp_path / "maps"
    code = main(["measure", "--method", "pmd", "--size", "16", "--maps", str(maps), *args])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.count("\n") == 0, err
    for word in words:
        assert word in err, err
    assert not maps.exists()  # nothing written


def test_output_directories_and_flags_of_the_other_instrument(tmp_path, capsys):
    afile = tmp_path / "file.txt"
    afile.write_text("x")
    assert main(["measure", "--method", "pmd", "--size", "16", "--maps", str(afile)]) == 2
    assert "is not a directory" in capsys.readouterr().err
    assert main(["measure", "--size", "16", "--maps", str(tmp_path / "m")]) == 2
    assert "--maps: belongs to phase measuring (--method pmd)" in capsys.readouterr().err
    assert main(["measure", "--size", "16", "--frames", str(tmp_path / "m")]) == 2
    assert "--frames: belongs to phase measuring (--method pmd)" in capsys.readouterr().err
    missing = tmp_path / "no" / "such"
    assert main(["measure", "--method", "pmd", "--size", "16", "--frames", str(missing)]) == 2
    assert "does not exist" in capsys.readouterr().err
