"""Solid link meshes (:mod:`previewctl.scene.solid`): an obstacle inside a link collides."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
import pytest

from previewctl.index.evaluator import Evaluator
from previewctl.robot.model import Robot
from previewctl.scene.motion import Static
from previewctl.scene.shapes import Obstacle, Scene, Sphere
from previewctl.scene.solid import SolidMesh, winding_number

PANDA_Q0 = np.array([-0.231, -0.1124, -0.2518, -2.1351, -0.0842, 2.0147, 0.785])


def l_prism() -> coal.BVHModelOBBRSS:
    """A closed, non-convex mesh: the L = [0,2]x[0,1] ∪ [0,1]x[0,2] extruded over z in [0, 1] [m]."""
    outline = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=float)
    vertices = np.vstack([np.c_[outline, np.zeros(6)], np.c_[outline, np.ones(6)]])
    fan = [(0, i, i + 1) for i in range(1, 5)]  # the L is star-shaped from (0, 0)
    triangles = [(a, c, b) for a, b, c in fan] + [(a + 6, b + 6, c + 6) for a, b, c in fan]
    for i in range(6):
        j = (i + 1) % 6
        triangles += [(i, j, j + 6), (i, j + 6, i + 6)]
    mesh = coal.BVHModelOBBRSS()
    mesh.beginModel(len(triangles), len(vertices))
    mesh.addVertices(vertices)
    mesh.addTriangles(np.array(triangles, dtype=int))
    mesh.endModel()
    return mesh


def test_winding_number_tells_inside_from_the_concavity() -> None:
    solid = SolidMesh.of(l_prism())
    assert winding_number(solid.vertices, solid.triangles, np.array([0.5, 0.5, 0.5])) == pytest.approx(1.0)
    assert winding_number(solid.vertices, solid.triangles, np.array([1.5, 1.5, 0.5])) == pytest.approx(0.0, abs=1e-12)
    assert not solid.contains(np.array([1.5, 1.5, 0.5]))  # inside the hull, outside the solid
    assert not solid.contains(np.array([5.0, 5.0, 5.0]))


def test_solid_distance_inside_is_the_hull_penetration_and_outside_the_surface_distance() -> None:
    mesh, ball = l_prism(), coal.Sphere(0.1)
    solid, at = SolidMesh.of(mesh), pin.SE3.Identity()

    def surface(centre: np.ndarray) -> tuple[float, np.ndarray]:
        result = coal.DistanceResult()
        d = coal.distance(mesh, coal.Transform3s(), ball, coal.Transform3s(np.eye(3), centre),
                          coal.DistanceRequest(), result)
        return float(d), result.getNearestPoint2()

    inside = np.array([0.5, 0.5, 0.5])
    d, witness = surface(inside)
    assert d == pytest.approx(0.4, abs=1e-9), "Coal measures to the triangles: 0.5 - 0.1 m"
    # the hull's nearest face is 0.5 m away, so the ball is 0.6 m deep
    assert solid.solid_distance(d, at, witness, ball, pin.SE3(np.eye(3), inside)) == pytest.approx(-0.6, abs=1e-6)
    notch = np.array([1.5, 1.5, 0.5])  # in the L's notch: clear of the solid by 0.5 - 0.1 m
    d, witness = surface(notch)
    assert solid.solid_distance(d, at, witness, ball, pin.SE3(np.eye(3), notch)) == d == pytest.approx(0.4)


def test_a_ball_inside_a_panda_link_collides_in_the_exact_check(panda_mesh: Robot, panda: Robot) -> None:
    # issue 13: a 2 cm ball at the centre of panda_link4 read clear with geometry="mesh"
    (link4,) = [g for g in panda_mesh.collision_model.geometryObjects if g.name.startswith("panda_link4")]
    data = panda_mesh.model.createData()
    pin.forwardKinematics(panda_mesh.model, data, PANDA_Q0)
    placement = data.oMi[link4.parentJoint] * link4.placement
    vertices = np.asarray(link4.geometry.vertices())
    centre = placement.act((vertices.min(axis=0) + vertices.max(axis=0)) / 2)
    raw = coal.distance(link4.geometry, coal.Transform3s(placement.rotation, placement.translation),
                        coal.Sphere(0.01), coal.Transform3s(np.eye(3), centre),
                        coal.DistanceRequest(), coal.DistanceResult())
    assert raw > 0, "the premise: Coal's mesh distance is to the surface"
    scene = Scene((Obstacle("ball", Sphere(0.01), Static(centre)),))
    exact = Evaluator(panda_mesh, scene)(PANDA_Q0[None, :])
    convex = Evaluator(panda, scene)(PANDA_Q0[None, :])
    k = panda_mesh.guarded_links.index("panda_link4")
    assert exact.collision[0] and exact.link_distances[0, k] < -0.02
    assert exact.link_distances[0, k] == pytest.approx(convex.link_distances[0, k], abs=1e-6)
    # the other links, with the ball outside them, keep their surface distances
    others = [i for i in range(len(panda_mesh.guarded_links)) if i != k]
    assert (exact.link_distances[0, others] > 0).all()
