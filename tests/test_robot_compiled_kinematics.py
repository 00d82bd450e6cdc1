"""The compiled kinematics against Pinocchio (random chains, every covered joint kind, shipped arms), closed forms."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from helpers import random_chain_urdf

import previewctl
from previewctl.kinematics import FrameKinematics
from previewctl.robot.compiled_kinematics import CONTINUOUS, PRISMATIC, REVOLUTE, CompiledKinematics
from previewctl.search.newton import NewtonRedundancy

TOLERANCE = 1e-12


def random_configurations(model: pin.Model, rng: np.random.Generator, count: int) -> np.ndarray:
    """``count`` configurations of ``model``: angles in ``[-pi, pi]``, (cos, sin) pairs on the circle, any limits
    ignored (the kinematics has none)."""
    return np.array([pin.integrate(model, pin.neutral(model), rng.uniform(-np.pi, np.pi, model.nv))
                     for _ in range(count)])


def assert_matches_pinocchio(model: pin.Model, Q: np.ndarray) -> None:
    """Every joint placement (``data.oMi``) and every frame's placement (``data.oMf``) and ``LOCAL_WORLD_ALIGNED``
    Jacobian equal Pinocchio's to :data:`TOLERANCE`, all frames asked at once."""
    compiled = CompiledKinematics.of(model)
    assert compiled is not None
    data = model.createData()
    joints = np.arange(model.njoints)
    placements, _ = compiled.frames(Q, joints, np.broadcast_to(np.eye(4), (model.njoints, 4, 4)), 0)
    frames = list(model.frames)
    H, J = compiled.frames(Q, np.array([f.parentJoint for f in frames]),
                           np.array([f.placement.homogeneous for f in frames]))
    for b, q in enumerate(Q):
        pin.framesForwardKinematics(model, data, q)
        for j in range(model.njoints):
            np.testing.assert_allclose(placements[b, j], data.oMi[j].homogeneous, rtol=0, atol=TOLERANCE)
        for k in range(len(frames)):
            expected = pin.computeFrameJacobian(model, data, q, k, pin.LOCAL_WORLD_ALIGNED)
            np.testing.assert_allclose(J[b, k], expected, rtol=0, atol=TOLERANCE)
            np.testing.assert_allclose(H[b, k], data.oMf[k].homogeneous, rtol=0, atol=TOLERANCE)


@pytest.mark.parametrize("seed", range(6))
def test_random_urdf_chains_match_pinocchio(seed: int) -> None:
    rng = np.random.default_rng(seed)
    model = pin.buildModelFromXML(random_chain_urdf(rng, int(rng.integers(1, 9))))
    assert_matches_pinocchio(model, random_configurations(model, rng, 8))


def every_kind() -> pin.Model:
    """A tree from a URDF with every joint kind Pinocchio makes of one: revolute, prismatic and continuous joints about
    the x, y, z axes and about others, and fixed joints between them; two branches off link 2."""
    rng = np.random.default_rng(7)

    def origin() -> str:
        xyz, rpy = rng.uniform(-0.4, 0.4, 3), rng.uniform(-np.pi, np.pi, 3)
        return f'<origin xyz="{" ".join(map(str, xyz.tolist()))}" rpy="{" ".join(map(str, rpy.tolist()))}"/>'

    limit = '<limit lower="-3" upper="3" effort="1" velocity="1"/>'
    joints = [("revolute", "1 0 0", 0), ("prismatic", "0 1 0", 1), ("revolute", "0.6 0 0.8", 2),
              ("fixed", "0 0 1", 3), ("continuous", "0 0 1", 4), ("prismatic", "0 0.8 -0.6", 5),
              ("continuous", "0.48 0.6 0.64", 2), ("revolute", "0 1 0", 7), ("fixed", "0 0 1", 8),
              ("prismatic", "0 0 1", 9), ("continuous", "1 0 0", 10)]
    parts = ['<robot name="every_kind">', '<link name="l0"/>']
    for k, (kind, axis, parent) in enumerate(joints, start=1):
        parts += [f'<link name="l{k}"/>', f'<joint name="j{k}" type="{kind}"><parent link="l{parent}"/>'
                  f'<child link="l{k}"/>{origin()}<axis xyz="{axis}"/>{limit if kind != "continuous" else ""}</joint>']
    return pin.buildModelFromXML("\n".join([*parts, "</robot>"]))


def test_every_joint_kind_and_a_tree_match_pinocchio() -> None:
    model = every_kind()
    compiled = CompiledKinematics.of(model)
    assert compiled is not None
    assert [model.joints[j].shortname() for j in range(1, model.njoints)] == [
        "JointModelRX", "JointModelPY", "JointModelRevoluteUnaligned", "JointModelRUBZ", "JointModelPrismaticUnaligned",
        "JointModelRevoluteUnboundedUnaligned", "JointModelRY", "JointModelPZ", "JointModelRUBX"]
    assert compiled.kind[1:].tolist() == [REVOLUTE, PRISMATIC, REVOLUTE, CONTINUOUS, PRISMATIC, CONTINUOUS,
                                          REVOLUTE, PRISMATIC, CONTINUOUS]
    assert_matches_pinocchio(model, random_configurations(model, np.random.default_rng(3), 8))


@pytest.mark.parametrize("name", ["panda", "ur5", "xarm7"])
def test_shipped_arms_match_pinocchio(name: str) -> None:
    robot = previewctl.load_robot(name)
    assert_matches_pinocchio(robot.model, robot.random_configurations(np.random.default_rng(11), 8))


def test_one_revolute_joint_in_closed_form() -> None:
    """One joint about z at the origin, a frame ``l`` along x: the frame at ``l (cos θ, sin θ, 0)`` moves with
    ``(-l sin θ, l cos θ, 0, 0, 0, 1)``."""
    model, length, theta = pin.Model(), 0.7, 0.4
    model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "z")
    compiled = CompiledKinematics.of(model)
    assert compiled is not None
    offset = np.eye(4)
    offset[0, 3] = length
    H, J = compiled.frames(np.array([[theta]]), np.array([1]), offset[None])
    c, s = np.cos(theta), np.sin(theta)
    np.testing.assert_allclose(H[0, 0, :3, 3], [length * c, length * s, 0.0], atol=1e-15)
    np.testing.assert_allclose(H[0, 0, :2, :2], [[c, -s], [s, c]], atol=1e-15)
    np.testing.assert_allclose(J[0, 0, :, 0], [-length * s, length * c, 0, 0, 0, 1], atol=1e-15)


@pytest.mark.parametrize("joint", [pin.JointModelFreeFlyer(), pin.JointModelSpherical(), pin.JointModelPlanar()])
def test_uncovered_joints_leave_pinocchio_in_charge(joint: pin.JointModel) -> None:
    """A joint the kernel does not cover: no compiled view, and a compiled reader falls back to Pinocchio with the
    same numbers as a plain one."""
    model = pin.Model()
    model.addJoint(model.addJoint(0, pin.JointModelRX(), pin.SE3.Random(), "a"), joint, pin.SE3.Random(), "b")
    model.addFrame(pin.Frame("tip", 2, 0, pin.SE3.Random(), pin.FrameType.OP_FRAME))
    assert CompiledKinematics.of(model) is None
    Q = random_configurations(model, np.random.default_rng(5), 4)
    frames = (model.getFrameId("tip"),)
    compiled, plain = FrameKinematics(model, frames, compiled=True)(Q), FrameKinematics(model, frames)(Q)
    for a, b in zip(compiled, plain, strict=True):
        np.testing.assert_array_equal(a, b)


def test_compiled_reader_matches_pinocchio_reader(panda: previewctl.Robot) -> None:
    """The batched frame placements and Jacobians of :class:`FrameKinematics`, compiled or not, agree."""
    frames = (*panda.control_frame_ids, panda.tip_frame_id)
    Q = panda.random_configurations(np.random.default_rng(2), 16)
    fast = FrameKinematics(panda.model, frames, joints=(0, 3, 5), compiled=True)
    slow = FrameKinematics(panda.model, frames, joints=(0, 3, 5))
    for a, b in zip(fast(Q), slow(Q), strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=TOLERANCE)
    np.testing.assert_allclose(fast.joint_placements, slow.joint_placements, rtol=0, atol=TOLERANCE)


def test_newton_hand_matches_pinocchio(panda: previewctl.Robot) -> None:
    """The Newton map's hand placements and Jacobians (compiled) equal ``pin.computeFrameJacobian``'s."""
    Q = panda.random_configurations(np.random.default_rng(4), 8)
    placements, jacobians = NewtonRedundancy(panda)._hand(Q)
    data = panda.model.createData()
    for b, q in enumerate(Q):
        expected = pin.computeFrameJacobian(panda.model, data, q, panda.tip_frame_id, pin.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(jacobians[b], expected, rtol=0, atol=TOLERANCE)
        np.testing.assert_allclose(placements[b], data.oMf[panda.tip_frame_id].homogeneous, rtol=0, atol=TOLERANCE)
