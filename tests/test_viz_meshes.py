"""Tests of :mod:`previewctl.viz.meshes` and :mod:`previewctl.viz.arm_meshes`: Coal shapes and URDF visuals."""

from __future__ import annotations

from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest
from helpers import random_chain_urdf

from previewctl.errors import PreviewctlError
from previewctl.index.load import load_robot, load_visual
from previewctl.robot.model import Robot
from previewctl.sim.schema import RobotSpec
from previewctl.viz.arm_meshes import ARM_RGBA, ArmMeshes
from previewctl.viz.meshes import PLANE_THICKNESS, file_parts, shape_mesh, shape_parts


def _tetrahedron() -> coal.BVHModelOBBRSS:
    model = coal.BVHModelOBBRSS()
    model.beginModel(4, 4)
    model.addVertices(np.array([[0.0, 0.0, 0.0], [0.3, 0.0, 0.0], [0.0, 0.2, 0.0], [0.0, 0.0, 0.1]]))
    model.addTriangles(np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]))
    model.endModel()
    return model


def _convex_box() -> coal.Convex:
    mesh = coal.BVHModelOBBRSS()
    mesh.beginModel(12, 8)
    corners = np.array([[x, y, z] for x in (-0.1, 0.1) for y in (-0.2, 0.2) for z in (-0.05, 0.05)])
    mesh.addVertices(corners)
    mesh.addTriangles(np.array([[0, 1, 2], [1, 2, 3], [4, 5, 6], [5, 6, 7], [0, 1, 4], [1, 4, 5],
                                [2, 3, 6], [3, 6, 7], [0, 2, 4], [2, 4, 6], [1, 3, 5], [3, 5, 7]]))
    mesh.endModel()
    mesh.buildConvexHull(True, "Qt")
    return mesh.convex


# (shape, expected lower and upper corner of its bounding box [m], tolerance [m])
CASES = {
    "sphere": (coal.Sphere(0.2), [-0.2] * 3, [0.2] * 3, 0.01),  # an icosphere: vertices on the sphere
    "ellipsoid": (coal.Ellipsoid(0.1, 0.2, 0.3), [-0.1, -0.2, -0.3], [0.1, 0.2, 0.3], 0.015),
    "box": (coal.Box(0.1, 0.2, 0.3), [-0.05, -0.1, -0.15], [0.05, 0.1, 0.15], 1e-12),
    "capsule": (coal.Capsule(0.05, 0.4), [-0.05, -0.05, -0.25], [0.05, 0.05, 0.25], 1e-3),
    "cylinder": (coal.Cylinder(0.05, 0.4), [-0.05, -0.05, -0.2], [0.05, 0.05, 0.2], 1e-3),
    "cone": (coal.Cone(0.05, 0.4), [-0.05, -0.05, -0.2], [0.05, 0.05, 0.2], 1e-3),  # centred, as Coal's
    "convex": (_convex_box(), [-0.1, -0.2, -0.05], [0.1, 0.2, 0.05], 1e-12),
    "mesh": (_tetrahedron(), [0.0, 0.0, 0.0], [0.3, 0.2, 0.1], 1e-12),
    "halfspace": (coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.5), [-1.0, -1.0, 0.5 - PLANE_THICKNESS / 2],
                  [1.0, 1.0, 0.5 + PLANE_THICKNESS / 2], 1e-12),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_each_coal_shape_gives_a_closed_mesh_with_its_extents(name: str) -> None:
    shape, low, high, tol = CASES[name]
    mesh = shape_mesh(shape, plane_size=2.0)
    np.testing.assert_allclose(mesh.bounds[0], low, atol=tol)
    np.testing.assert_allclose(mesh.bounds[1], high, atol=tol)
    assert mesh.is_watertight
    (part,) = shape_parts(shape, (0.1, 0.2, 0.3, 0.5))
    assert part.vertices.dtype == np.float32 and part.faces.dtype == np.uint32 and part.rgba == (0.1, 0.2, 0.3, 0.5)
    np.testing.assert_allclose(part.extents, np.subtract(high, low), atol=tol + 1e-6)


def test_a_tilted_plane_is_a_square_on_its_boundary() -> None:
    normal = np.array([1.0, 2.0, 2.0]) / 3.0
    mesh = shape_mesh(coal.Plane(normal, 0.3), plane_size=1.5)
    heights = mesh.vertices @ normal
    np.testing.assert_allclose(heights, 0.3, atol=PLANE_THICKNESS / 2 + 1e-12)
    in_plane = mesh.vertices - np.outer(heights, normal)
    np.testing.assert_allclose(np.linalg.norm(in_plane, axis=1), 1.5 / np.sqrt(2), rtol=1e-9)  # the corners


def test_an_unknown_shape_is_named() -> None:
    triangle = coal.TriangleP(np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    with pytest.raises(PreviewctlError, match=r"cannot draw a Coal TriangleP; drawable: sphere, ellipsoid, box"):
        shape_mesh(triangle)


def test_dae_file_keeps_its_material_colours() -> None:
    """The Panda's link 6 has white, dark grey and small coloured parts; together they are Coal's mesh."""
    _, visual = load_visual("panda")
    obj = visual.geometryObjects[visual.getGeometryId("panda_link6_0")]
    parts = file_parts(obj.meshPath, obj.meshScale, ARM_RGBA)
    assert parts is not None
    colours = {p.rgba for p in parts}
    assert {(1.0, 1.0, 1.0, 1.0), (0.251, 0.251, 0.251, 1.0)} <= colours and ARM_RGBA not in colours
    vertices = np.vstack([p.vertices for p in parts])
    coal_vertices = np.asarray(obj.geometry.vertices())
    np.testing.assert_allclose(vertices.min(axis=0), coal_vertices.min(axis=0), atol=1e-6)
    np.testing.assert_allclose(vertices.max(axis=0), coal_vertices.max(axis=0), atol=1e-6)
    assert sum(len(p.vertices) for p in parts) == len(coal_vertices)  # repeated vertices merged, as Coal does


def test_unreadable_file_gives_none(tmp_path: Path) -> None:
    broken = tmp_path / "broken.dae"
    broken.write_text("<not collada")
    assert file_parts(broken, np.ones(3), ARM_RGBA) is None


def test_planar4_visuals_sit_on_its_links(planar4: Robot) -> None:
    """planar4's visual cylinders (uncoloured in the URDF: ARM_RGBA) are centred 0.375 m along each link."""
    arm = ArmMeshes(planar4, RobotSpec(source="planar4"))
    q = np.array([0.3, -1.1, 0.7, 2.0])
    assert len(arm.links) == 4 and all(p.rgba == ARM_RGBA for link in arm.links for p in link.parts)
    angles = np.cumsum(q)
    joints = np.vstack([[0.0, 0.0], 0.75 * np.cumsum(np.column_stack([np.cos(angles), np.sin(angles)]), axis=0)])
    for i, placement in enumerate(arm.placements(q)):
        centre = joints[i] + 0.375 * np.array([np.cos(angles[i]), np.sin(angles[i])])
        np.testing.assert_allclose(placement.translation, [*centre, 0.0], atol=1e-12)
        np.testing.assert_allclose(placement.rotation[:, 2], [np.cos(angles[i]), np.sin(angles[i]), 0.0], atol=1e-12)
        np.testing.assert_allclose(arm.links[i].parts[0].extents, [0.06, 0.06, 0.75], atol=1e-3)


def test_panda_visuals_follow_the_reduced_model(panda: Robot) -> None:
    """A reduced-model q moves the full model's visuals with the reduced model's joints (fingers locked)."""
    arm = ArmMeshes(panda, RobotSpec(source="panda"))
    q = panda.random_configurations(np.random.default_rng(3), 1)[0]
    data = panda.model.createData()
    pin.forwardKinematics(panda.model, data, q)
    placements = dict(zip((link.name for link in arm.links), arm.placements(q), strict=True))
    for body in ("panda_link3", "panda_link7", "panda_hand"):
        obj = arm.visual.geometryObjects[arm.visual.getGeometryId(f"{body}_0")]
        joint = panda.model.getJointId(arm.model.names[obj.parentJoint])  # the same joint in the reduced model
        expected = data.oMi[joint] * obj.placement
        np.testing.assert_allclose(placements[f"{body}_0"].homogeneous, expected.homogeneous, atol=1e-9)
    assert {link.body for link in arm.links} >= {"panda_leftfinger", "panda_hand"}


def test_urdf_without_visuals_is_drawn_with_its_collision_geometry(tmp_path: Path) -> None:
    urdf = tmp_path / "chain.urdf"
    urdf.write_text(random_chain_urdf(np.random.default_rng(5), 5))
    robot = load_robot(urdf)
    arm = ArmMeshes(robot, RobotSpec(source=str(urdf)))
    assert len(arm.links) == 5 and all(link.parts for link in arm.links)
    assert len(arm.placements(np.zeros(robot.model.nq))) == 5
