"""The sensor's table: full well, read noise, bit depth, black level and the noise's seed.
Off (``full_well_e`` unset: the noiseless float radiance) unless a scene file has a
``[sensor]`` table or a key of it is set."""

from __future__ import annotations

import math
from dataclasses import dataclass

from glshade.errors import SceneError
from glshade.params import Table, param

BIT_DEPTHS = (8, 10, 12, 16)
DEFAULT_FULL_WELL_E = 10000.0
#: ``black_level_dn = "auto"`` is at least full scale over this (64 DN at 12 bits) ...
AUTO_BLACK_SHARE = 64
#: ... and at least this many read-noise σ (a sensor whose read noise is a large share of
#: its range), so that read noise at the fringes' dark troughs is never clipped at 0 DN.
AUTO_BLACK_SIGMAS = 6.0
#: A black level stays below this share of full scale (``"auto"`` is capped at it).
MAX_BLACK_SHARE = 0.25


def check_bit_depth(values: dict) -> None:
    """The bit depth is one a camera stores."""
    if values["bit_depth"] not in BIT_DEPTHS:
        allowed = Sensor.declaration("bit_depth").allowed()
        raise SceneError("sensor.bit_depth", allowed, values["bit_depth"])


def check_black_level(values: dict) -> None:
    """A black level given in DN stays below a quarter of the bit depth's full scale."""
    black = values["black_level_dn"]
    if black == "auto" or values["bit_depth"] not in BIT_DEPTHS:
        return
    top = max_black_dn(values["bit_depth"])
    if black > top:
        raise SceneError(
            "sensor.black_level_dn",
            f"a number from 0 to {top} DN (a quarter of the {values['bit_depth']}-bit full "
            'scale) or "auto"',
            black,
        )


def max_black_dn(bit_depth: int) -> int:
    """The largest black level (DN) a ``bit_depth`` sensor takes: a quarter of full scale."""
    return int(MAX_BLACK_SHARE * (2**bit_depth - 1))


#: The most electrons a pixel may hold at radiance 1 (inclusive): real sensors hold 1e3 to
#: 1e6; beyond 1e9 the shot noise is negligible, and a Poisson draw of 1e300 electrons
#: cannot be made.
MAX_FULL_WELL_E = 1e9


@dataclass(frozen=True)
class Sensor(Table):
    """The camera's sensor (electrons, bits, DN)."""

    table = "sensor"
    table_checks = (check_bit_depth, check_black_level)

    full_well_e: float | None = param(
        "sensor.full_well_e", "e-", None,
        "electrons at radiance 1 (the emitter's peak in a perfect mirror), which fill the "
        "range from the black level to full scale; unset: no sensor (a [sensor] table sets "
        f"{DEFAULT_FULL_WELL_E:g})",
        lo=1.0, hi=MAX_FULL_WELL_E, closed=True, flag="--full-well",
    )  # fmt: skip
    read_noise_e: float = param(
        "sensor.read_noise_e", "e-", 5.0, "read noise, electrons rms", lo=0.0,
        hi=MAX_FULL_WELL_E, closed=True, flag="--read-noise",
    )  # fmt: skip
    bit_depth: int = param(
        "sensor.bit_depth", "bit", 12, "bits of the stored image", value_type="integer", lo=1,
        hi=64, allowed_text="one of " + ", ".join(map(str, BIT_DEPTHS)), flag="--bit-depth",
    )  # fmt: skip
    black_level_dn: float | str = param(
        "sensor.black_level_dn", "DN", "auto",
        "the offset the sensor adds before clipping at 0 (a camera's black level), kept in "
        f'the recorded frames; "auto": full scale / {AUTO_BLACK_SHARE} (64 DN at 12 bits) or '
        f"{AUTO_BLACK_SIGMAS:g} read-noise σ where that is more, at most a quarter of full "
        "scale; 0: none (read noise below 0 is clipped)",
        lo=0.0, closed=True, keywords=("auto",),
        allowed_text="a number from 0 to a quarter of the full scale in DN (1023 at 12 bits)",
        flag="--black-level",
    )  # fmt: skip
    seed: int = param(
        "sensor.seed", "", 0, "seed of the noise (with the scene and the exposure number)",
        value_type="integer", lo=0, hi=2**63 - 1, flag="--seed",
    )  # fmt: skip

    @property
    def on(self) -> bool:
        return self.full_well_e is not None

    @property
    def full_scale_dn(self) -> int:
        """The largest stored value, ``2^bit_depth - 1`` DN."""
        return 2**self.bit_depth - 1

    @property
    def black_dn(self) -> float:
        """The black level in DN, ``"auto"`` worked out (a whole number of DN; 0 without a
        sensor)."""
        if not self.on:
            return 0
        if self.black_level_dn != "auto":
            return float(self.black_level_dn)
        assert self.full_well_e is not None
        read_dn = self.read_noise_e * self.full_scale_dn / self.full_well_e
        wanted = max(2**self.bit_depth / AUTO_BLACK_SHARE, AUTO_BLACK_SIGMAS * read_dn)
        return math.ceil(min(wanted, max_black_dn(self.bit_depth)))  # capped before ceil

    @property
    def black_level(self) -> float:
        """The black level in recorded units (full scale 1): ``black_dn / (2^bits - 1)``."""
        return self.black_dn / self.full_scale_dn
