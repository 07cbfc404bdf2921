"""The sensor's table: full well, read noise, bit depth and the noise's seed. Off
(``full_well_e`` unset: the noiseless float radiance) unless a scene file has a
``[sensor]`` table or a key of it is set."""

from __future__ import annotations

from dataclasses import dataclass

from glshade.errors import SceneError
from glshade.params import Table, param

BIT_DEPTHS = (8, 10, 12, 16)
DEFAULT_FULL_WELL_E = 10000.0


def check_bit_depth(values: dict) -> None:
    """The bit depth is one a camera stores."""
    if values["bit_depth"] not in BIT_DEPTHS:
        allowed = Sensor.declaration("bit_depth").allowed()
        raise SceneError("sensor.bit_depth", allowed, values["bit_depth"])


#: The most electrons a pixel may hold at radiance 1 (exclusive): real sensors hold 1e3 to
#: 1e6; beyond 1e9 the shot noise is negligible, and a Poisson draw of 1e300 electrons
#: cannot be made.
MAX_FULL_WELL_E = 1e9


@dataclass(frozen=True)
class Sensor(Table):
    """The camera's sensor (electrons, bits)."""

    table = "sensor"
    table_checks = (check_bit_depth,)

    full_well_e: float | None = param(
        "sensor.full_well_e", "e-", None,
        "electrons at radiance 1 (the emitter's peak in a perfect mirror); unset: no sensor "
        f"(a [sensor] table sets {DEFAULT_FULL_WELL_E:g})",
        lo=0.0, hi=MAX_FULL_WELL_E, flag="--full-well",
    )  # fmt: skip
    read_noise_e: float = param(
        "sensor.read_noise_e", "e-", 5.0, "read noise, electrons rms", lo=0.0, closed=True,
        flag="--read-noise",
    )  # fmt: skip
    bit_depth: int = param(
        "sensor.bit_depth", "bit", 12, "bits of the stored image", value_type="integer", lo=1,
        hi=64, allowed_text="one of " + ", ".join(map(str, BIT_DEPTHS)), flag="--bit-depth",
    )  # fmt: skip
    seed: int = param(
        "sensor.seed", "", 0, "seed of the noise (with the scene and the exposure number)",
        value_type="integer", lo=0, hi=2**63 - 1, flag="--seed",
    )  # fmt: skip

    @property
    def on(self) -> bool:
        return self.full_well_e is not None
