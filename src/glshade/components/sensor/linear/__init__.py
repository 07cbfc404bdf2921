"""The sensor (``[sensor]`` of a scene file): photon and read noise, full well, black level,
quantisation.

Off unless the scene has a ``[sensor]`` table (``full_well_e`` unset: the noiseless float
radiance). When on, a rendered radiance image ``L`` (1 = the emitter's peak
seen in a perfect mirror) taken with the camera's exposure ``g`` (``camera.exposure``;
``"auto"``: 0.9 over the brightest point of the defect-free scene) becomes

    electrons = Poisson(g · L · full_well_e) + Normal(0, read_noise_e)
    recorded  = b + (1 - b) · electrons / full_well_e
    stored    = round(clip(recorded, 0, 1) · (2^bits - 1)) / (2^bits - 1)

in recorded units (1 = full scale), quantised to ``bit_depth``, with ``b`` the black level
(``black_level_dn / (2^bits - 1)``): the offset a camera adds before its converter clips at
0, so read noise in the dark is kept, not clipped; the full well fills the range from the
black level to full scale, so ``g · L = 1`` still just saturates and ``"auto"`` keeps a
tenth of that range as headroom. The recorded values keep the black level (a camera's raw
frames do); a decoder subtracts it (:attr:`Sensor.black_level`). The noise is drawn in
NumPy (identical on every GPU) from ``seed``, the scene itself (every other parameter: two
different images never share a noise pattern) and the exposure number (two exposures of
one scene differ: what the metric's noise floor compares). An image is developed after
read-back. A frame stack (a phase-measuring sequence) is recorded where it was traced, by
the GPU's record pass (``record.glsl`` in this folder): the same model in float32, its
noise drawn from Philox4x32-10 keyed by a digest of the scene (the seed in it), the frame
and the recording, and counted by the pixel (:mod:`glshade.gpu.sequence`); this NumPy
develop stays its reference. Table:
:class:`~glshade.components.sensor.linear.table.Sensor`.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from typing import Any

import numpy as np

from glshade.components.base import SceneView, SensorComponent
from glshade.components.sensor.linear.table import DEFAULT_FULL_WELL_E, Sensor
from glshade.frame import exposure_gain


def scene_digest(scene: SceneView) -> bytes:
    """A SHA-256 digest of every parameter of ``scene`` (the sensor's seed among them)."""
    described = json.dumps(scene.to_dict(), sort_keys=True, default=str).encode()
    return hashlib.sha256(described).digest()


def noise_key(scene: SceneView, exposure: int) -> list[int]:
    """The noise stream's seed: the sensor's seed, a digest of the rest of the scene and
    the exposure number."""
    digest = int.from_bytes(scene_digest(scene)[:8], "little")
    return [int(scene.sensor.seed), digest, int(exposure)]


class LinearSensor(SensorComponent):
    name = "linear"
    doc = (
        "photon (Poisson) and read noise, full well, black level and quantisation, when a "
        "[sensor] table is given"
    )
    table = Sensor

    def read_file(
        self, values: dict[str, Any], current: dict[str, Any] | None = None
    ) -> dict[str, Any]:
        """A ``[sensor]`` table (or a changed key) switches the sensor on with a full well of
        :data:`DEFAULT_FULL_WELL_E` electrons unless it gives one."""
        if "full_well_e" not in values and (current is None or current.get("full_well_e") is None):
            values = {**values, "full_well_e": DEFAULT_FULL_WELL_E}
        return values

    def write_file(self, values: dict[str, Any]) -> dict[str, Any]:
        return values if values.get("full_well_e") is not None else {}

    def shades_from_emitter_map(self, scene: SceneView) -> bool:
        return not scene.sensor.on

    def records(self, scene: SceneView) -> bool:
        return scene.sensor.on

    def record_glsl(self, scene: SceneView) -> tuple[str, ...]:
        return ("record.glsl",) if scene.sensor.on else ()

    def record_uniforms(self, scene: SceneView, gain: float) -> dict[str, object]:
        sensor = scene.sensor
        return {
            "u_sensor_full_well_e": float(sensor.full_well_e or 0.0),
            "u_sensor_read_noise_e": float(sensor.read_noise_e),
            "u_sensor_black": float(sensor.black_level),
            "u_sensor_levels": float(sensor.full_scale_dn),
            "u_sensor_gain": float(gain),
        }

    def frame_keys(self, scene: SceneView, frames: Sequence[Any], recording: int) -> np.ndarray:
        digest = scene_digest(scene)
        keys = np.empty((len(frames), 2), np.uint32)
        for index, frame in enumerate(frames):
            named = hashlib.sha256(digest + f"|{frame!r}|{int(recording)}".encode()).digest()
            keys[index] = np.frombuffer(named[:8], "<u4")
        return keys

    def develop(self, scene: SceneView, image: np.ndarray, exposure: int = 0) -> np.ndarray:
        sensor = scene.sensor
        if not sensor.on:
            return image
        assert sensor.full_well_e is not None  # on: set
        rng = np.random.default_rng(noise_key(scene, exposure))
        radiance = np.nan_to_num(np.asarray(image, np.float64), nan=0.0)
        radiance *= exposure_gain(scene.camera.exposure, radiance)  # "auto": from this image
        electrons = rng.poisson(np.maximum(radiance, 0.0) * sensor.full_well_e).astype(np.float64)
        if sensor.read_noise_e > 0:
            electrons += rng.normal(0.0, sensor.read_noise_e, radiance.shape)
        black = sensor.black_level
        recorded = black + (1.0 - black) * (electrons / sensor.full_well_e)
        levels = float(sensor.full_scale_dn)
        counts = np.round(np.clip(recorded, 0.0, 1.0) * levels)
        return (counts / levels).astype(np.float32)


COMPONENTS = (LinearSensor,)
