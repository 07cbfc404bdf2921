"""The part's table: its pose in the world frame (mm, degrees)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glshade.params import Table, param, turn_param
from glshade.poses import Placement, rotation_ypr


@dataclass(frozen=True)
class Part(Table):
    """Where the part stands: the origin of the frame its surface ``y = f(x, z)`` and its
    dent are written in, and that frame's turn (its own axes, yaw about ``y``, then pitch
    about ``x``, then roll about ``z``, right-handed)."""

    table = "part"

    position: tuple[float, float, float] = param(
        "part.position", "mm", (0.0, 0.0, 0.0),
        "the part's origin (the surface's apex, where its x and z are 0) in the world frame",
        value_type="vector", size=3, quiet=True,
    )  # fmt: skip
    yaw_deg: float = turn_param(
        "part.yaw_deg",
        "turn of the part about its own normal (+y): its x axis turns away from +x towards -z",
    )
    pitch_deg: float = turn_param(
        "part.pitch_deg",
        "tilt of the part about its own x axis (positive: its normal leans towards +z, its "
        "+z edge dips)",
    )
    roll_deg: float = turn_param(
        "part.roll_deg",
        "tilt of the part about its own z axis (positive: its +x edge rises, its normal "
        "leans towards -x)",
    )

    def placement(self) -> Placement:
        """The part's frame in the world: ``world = position + axes local``."""
        return Placement(
            np.asarray(self.position, np.float64),
            rotation_ypr(self.yaw_deg, self.pitch_deg, self.roll_deg),
        )
