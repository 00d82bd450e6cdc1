"""The visual meshes of an arm (from its URDF's ``<visual>`` elements) and where they are for a configuration.

The arm of a run is Pinocchio's reduced model (locked joints removed, :func:`~previewctl.index.load.load_robot`).
Its visual geometry belongs to the full model, so a configuration ``q`` of the reduced model is
spread onto the full one by joint name, with every locked joint at its neutral value (where the
loader locked it).
"""

from __future__ import annotations

from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin

from previewctl.index.load import load_visual
from previewctl.robot.model import Robot
from previewctl.sim.schema import RobotSpec
from previewctl.types import Array
from previewctl.viz.meshes import Part, file_parts, shape_parts

ARM_RGBA = (0.35, 0.55, 0.85, 1.0)
"""Colour [0, 1] of visual geometry that the URDF leaves uncoloured (Pinocchio's default grey)."""
_PINOCCHIO_DEFAULT_RGBA = (0.9, 0.9, 0.9, 1.0)


@dataclass(frozen=True, eq=False)
class LinkMesh:
    """One visual geometry object of the arm.

    Attributes:
        name: the geometry object's name (e.g. ``panda_link3_0``).
        body: the body (link) it is attached to.
        parts: its meshes, one per colour, in the geometry object's frame.
    """

    name: str
    body: str
    parts: tuple[Part, ...]


class ArmMeshes:
    """The visual meshes of a robot and their world placements for configurations of its reduced model.

    Args:
        robot: the loaded (reduced) robot.
        spec: how it was loaded (its source and package folders name the URDF).
    """

    def __init__(self, robot: Robot, spec: RobotSpec) -> None:
        self.model, self.visual = load_visual(spec.source, spec.package_dirs)
        self.data = self.model.createData()
        self.visual_data = self.visual.createData()
        self.links = tuple(self._link_mesh(obj) for obj in self.visual.geometryObjects)
        reduced = robot.model
        self._neutral = pin.neutral(self.model)
        self._q_index = np.concatenate([
            np.arange(self.model.idx_qs[self.model.getJointId(reduced.names[j])],
                      self.model.idx_qs[self.model.getJointId(reduced.names[j])] + reduced.nqs[j])
            for j in range(1, reduced.njoints)
        ]).astype(int)

    def _link_mesh(self, obj: pin.GeometryObject) -> LinkMesh:
        r, g, b, a = (float(c) for c in obj.meshColor)
        rgba = ARM_RGBA if np.allclose((r, g, b, a), _PINOCCHIO_DEFAULT_RGBA) else (r, g, b, a)
        parts = file_parts(obj.meshPath, obj.meshScale, rgba) if isinstance(obj.geometry, coal.BVHModelBase) else None
        if parts is None:  # a primitive, or a file trimesh cannot read: Coal's own geometry
            parts = shape_parts(obj.geometry, rgba)  # type: ignore[arg-type]
        body = str(self.model.frames[obj.parentFrame].name)
        return LinkMesh(str(obj.name), body, parts)

    def full_configuration(self, q: Array) -> Array:
        """``q`` of the reduced model as a configuration of the full model (locked joints at neutral)."""
        full = self._neutral.copy()
        full[self._q_index] = q
        return full

    def placements(self, q: Array) -> list[pin.SE3]:
        """World placement of each :attr:`links` entry at ``q`` (reduced model) [m]."""
        pin.forwardKinematics(self.model, self.data, self.full_configuration(q))
        pin.updateGeometryPlacements(self.model, self.data, self.visual, self.visual_data)
        return [pin.SE3(m) for m in self.visual_data.oMg]
