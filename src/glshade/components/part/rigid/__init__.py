"""The rigid part: the part's surface and dent, placed in the world by a pose.

Every other component writes the part in its own frame: the surface ``y = f(x, z)`` with
its apex at the origin, the dent at ``(defect.x0, defect.z0)`` on it. ``[part]`` places
that frame in the station's world frame (``part.position``, then ``yaw_deg``, ``pitch_deg``,
``roll_deg`` about its own axes); the renderer, the oracle and the instruments work in the
part's frame, the camera and the screen brought into it (:meth:`Scene.camera_pose`,
:meth:`Scene.emitter_plane`). The default stands the part at the world's origin,
unturned: the paper's rig. No shader code. Table:
:class:`~glshade.components.part.rigid.table.Part`.
"""

from __future__ import annotations

from glshade.components.base import PartComponent
from glshade.components.part.rigid.table import Part


class RigidPart(PartComponent):
    name = "rigid"
    doc = "the part's surface and dent placed in the world by a position and three turns"
    table = Part


COMPONENTS = (RigidPart,)
