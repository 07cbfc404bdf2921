"""How a PMD case is decoded and reconstructed (its settings, declared as ``measure.*``
parameters) and whether a scene can be measured by phase at all."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from glshade.components.base import no_sequence
from glshade.components.emitter.fringes.table import (
    fringes_of,
)
from glshade.errors import GlshadeError, SceneError
from glshade.params import Table, param
from glshade.scene import Scene

if TYPE_CHECKING:
    pass


#: The version of what a PMD case measures: part of a PMD sweep case's identity and of its
#: manifest. Raise it with any change that alters a number of a PMD record.
PMD_VERSION = 3


@dataclass(frozen=True)
class PmdSettings(Table):
    """How a PMD case is decoded and reconstructed.

    ``modulation_share``: a pixel is valid where every period's modulation is at least
    this share of ``amplitude`` times the image's response to the screen's white (its
    brightest pixel); ``min_modulation`` (recorded units) replaces that threshold when
    given. ``heights``: ``least-squares`` or ``frankot-chellappa`` (a rectangle of valid
    grid points only). ``grid_points``: the height grid's samples along its longer side;
    ``window_sigmas``: the grid spans the dent's centre ± this many σ (its largest);
    ``plane_sigmas``: tilt and offset are fitted where the Mahalanobis distance to the
    dent exceeds this."""

    table = "measure"

    modulation_share: float = param(
        "measure.modulation_share", "", 0.1,
        "pmd: a pixel is valid where every period's modulation is at least this share of "
        "the amplitude times the response to the screen's white",
        lo=0.0, hi=1.0, flag="--modulation-share",
    )  # fmt: skip
    min_modulation: float | None = param(
        "measure.min_modulation", "", None,
        "pmd: the least modulation (recorded units) of a valid pixel, instead of "
        "modulation_share (unset: modulation_share decides)",
        lo=0.0,
    )  # fmt: skip
    heights: str = param(
        "measure.heights", "", "least-squares",
        "pmd: how heights are integrated from the slopes (frankot-chellappa: a rectangle of "
        "valid grid points only)",
        value_type="choice", choices=("least-squares", "frankot-chellappa"), flag="--heights",
    )  # fmt: skip
    grid_points: int = param(
        "measure.grid_points", "", 160, "pmd: the height grid's samples along its longer side",
        value_type="integer", lo=16, hi=1024,
    )  # fmt: skip
    window_sigmas: float = param(
        "measure.window_sigmas", "", 5.0,
        "pmd: the height grid spans the dent's centre ± this many σ (its largest)",
        lo=0.0, hi=20.0, closed=True, nonzero=True, allowed_text="in (0, 20]",
    )  # fmt: skip
    plane_sigmas: float = param(
        "measure.plane_sigmas", "", 3.5,
        "pmd: tilt and offset are fitted where the Mahalanobis distance to the dent exceeds "
        "this (below window_sigmas)",
        lo=0.0, hi=20.0,
    )  # fmt: skip

    @staticmethod
    def _sigmas(values: dict[str, Any]) -> None:
        if not values["plane_sigmas"] < values["window_sigmas"]:
            raise SceneError(
                "measure.plane_sigmas",
                f"below measure.window_sigmas ({values['window_sigmas']:g})",
                values["plane_sigmas"],
            )

    table_checks = (_sigmas,)


def check_scene(scene: Scene) -> None:
    """Refuse, in one line, a scene a PMD station cannot decode: another emitter than the
    fringes, or a coding that cannot be decoded (an amplitude of 0 or above the offset:
    :meth:`~glshade.components.emitter.fringes.codec.FringeCodec.check_decodable`)."""
    if scene.active.emitter.measured_by != "pmd":
        raise GlshadeError(no_sequence(scene.emitter.kind))
    fringes_of(scene).codec.check_decodable()
