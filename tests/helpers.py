"""Plain helpers the test modules share: rotations, a planar4 scenario document, a scenario under the paper's
eq. 19, a random URDF chain, a control state made by hand, eq. 19 executed by the pseudo-inverse, and a child
process that Ctrl-C can interrupt.

Fixtures live in ``conftest.py``; functions that tests call directly live here and are imported as
``from helpers import rot_z`` (pytest puts ``tests/`` on ``sys.path``).
"""

from __future__ import annotations

import dataclasses
import signal
from collections.abc import Callable
from typing import Any

import numpy as np
from hypothesis import strategies as st
from numpy.typing import NDArray

from previewctl.control.base import ControlInfo, ControlState
from previewctl.control.execution import PseudoInverseExecution
from previewctl.control.params import ControllerParams
from previewctl.control.tracking import reference
from previewctl.kinematics import kinematics
from previewctl.path import HandPath
from previewctl.robot.model import Robot
from previewctl.sim.scenario import Scenario

Array = NDArray[np.float64]

# A hypothesis ``draw`` function, or a seeded numpy generator.
Source = np.random.Generator | Callable[[st.SearchStrategy[Any]], Any]

PLANAR_Q0 = [0.6, 1.0, -1.2, -1.0]
"""A planar4 start configuration [rad] whose hand is at :data:`PLANAR_START`."""
PLANAR_START = [1.9069, 1.0417]
"""planar4's hand [m] at :data:`PLANAR_Q0`."""


def rot_x(angle: float) -> Array:
    """Rotation about x by ``angle`` [rad]."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> Array:
    """Rotation about y by ``angle`` [rad]."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> Array:
    """Rotation about z by ``angle`` [rad]."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def tiny_planar_toml(name: str, sections: str) -> str:
    """A planar4 scenario file's text named ``name``: the hand from :data:`PLANAR_START` 0.1 m along −x in 1 s,
    no obstacle, followed by ``sections`` (more TOML: ``[timing]``, ``[output]``, ``[[obstacles]]`` ...)."""
    return (f'name = "{name}"\n[robot]\nsource = "planar4"\nq0 = {PLANAR_Q0}\n'
            f"[path]\nwaypoints = [{PLANAR_START}, [1.8069, 1.0417]]\nduration = 1.0\n{sections}")


def pseudoinverse(scenario: Scenario) -> Scenario:
    """``scenario`` with its controller executed by the paper's eq. 19 instead of the QP."""
    params = dataclasses.replace(scenario.controller.params, execution="pseudoinverse")
    return dataclasses.replace(scenario, controller=dataclasses.replace(scenario.controller, params=params))


def control_state(robot: Robot, q: Array, path: HandPath, *, t: float = 0.0, dt: float = 0.01,
                  frame_due: bool = True) -> ControlState:
    """The state of a control cycle at configuration ``q`` and time ``t`` [s] on ``path``, held for ``dt`` [s]."""
    q = np.asarray(q, dtype=float)
    return ControlState(q, t, kinematics(robot, q[None, :]), path, dt, frame_due)


def track(robot: Robot, state: ControlState, v: Array, params: ControllerParams) -> tuple[Array, ControlInfo]:
    """Eq. 19 for the null-space input ``v`` executed by the pseudo-inverse (clamping and saturation): the joint
    velocity applied [rad/s] and the cycle's reference and execution."""
    ref = reference(robot, state, v, params)
    executed = PseudoInverseExecution(robot, params)(state, ref)
    return executed.qdot, ControlInfo(ref, executed, state.frame_due)


def planar_doc(**sections: Any) -> dict[str, Any]:
    """A planar4 scenario document: the hand along a 0.5 m line in 5 s, no obstacle, controller ``none``.

    Each keyword replaces a whole section (``obstacles=[...]``, ``timing={"duration": 2.0}``, ...).
    Without ``timing`` the run lasts until the path ends (5 s).
    """
    doc: dict[str, Any] = {
        "name": "planar_test",
        "robot": {"source": "planar4", "q0": PLANAR_Q0},
        "path": {"waypoints": [PLANAR_START, [1.6069, 0.6417]], "duration": 5.0},
        "controller": {"name": "none"},
    }
    doc.update(sections)
    return doc


def _uniform(source: Source, low: float, high: float) -> float:
    """One float in ``[low, high]`` from either a numpy generator or a hypothesis ``draw``."""
    if isinstance(source, np.random.Generator):
        return float(source.uniform(low, high))
    return float(source(st.floats(low, high, allow_nan=False, allow_infinity=False)))


def random_chain_urdf(source: Source, n_joints: int) -> str:
    """URDF text of a random serial chain of ``n_joints`` revolute joints.

    Each joint has a random unit axis, a random origin (xyz in +-0.4 m, rpy in +-pi) and limits
    +-pi; each moving link carries a small cylinder collision. A fixed joint puts a ``tip`` link at
    a random offset from the last joint.

    Args:
        source: a seeded ``np.random.Generator`` or a hypothesis ``draw`` function.
        n_joints: number of revolute joints.
    """

    def xyz() -> str:
        return " ".join(repr(_uniform(source, -0.4, 0.4)) for _ in range(3))

    def rpy() -> str:
        return " ".join(repr(_uniform(source, -np.pi, np.pi)) for _ in range(3))

    def axis() -> str:
        # uniform on the sphere: z uniform in [-1, 1], azimuth uniform: always a unit vector
        z, phi = _uniform(source, -1.0, 1.0), _uniform(source, 0.0, 2.0 * np.pi)
        rho = float(np.sqrt(max(0.0, 1.0 - z * z)))
        return f"{rho * float(np.cos(phi))!r} {rho * float(np.sin(phi))!r} {z!r}"

    inertial = (
        '<inertial><mass value="1.0"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>'
    )
    parts = ['<?xml version="1.0"?>', '<robot name="random_chain">', '  <link name="link0"/>']
    for k in range(1, n_joints + 1):
        parts += [
            f'  <joint name="joint{k}" type="revolute">',
            f'    <parent link="link{k - 1}"/>',
            f'    <child link="link{k}"/>',
            f'    <origin xyz="{xyz()}" rpy="{rpy()}"/>',
            f'    <axis xyz="{axis()}"/>',
            f'    <limit lower="{-np.pi!r}" upper="{np.pi!r}" effort="10" velocity="1"/>',
            "  </joint>",
            f'  <link name="link{k}">',
            f"    {inertial}",
            "    <collision>",
            '      <origin xyz="0 0 0.05" rpy="0 0 0"/>',
            '      <geometry><cylinder radius="0.02" length="0.1"/></geometry>',
            "    </collision>",
            "  </link>",
        ]
    parts += [
        '  <joint name="tip_joint" type="fixed">',
        f'    <parent link="link{n_joints}"/>',
        '    <child link="tip"/>',
        f'    <origin xyz="{xyz()}" rpy="0 0 0"/>',
        "  </joint>",
        '  <link name="tip"/>',
        "</robot>",
    ]
    return "\n".join(parts) + "\n"


ARM7_JOINTS = (("0 0 1", 0.3), ("0 1 0", 0.0), ("0 0 1", 0.32), ("0 1 0", 0.0), ("0 0 1", 0.32), ("0 1 0", 0.0),
               ("1 0 0", 0.2))
"""Axis and height above the previous joint [m] of each joint of :func:`arm_urdf`'s default arm: yaw, then three
pitch-yaw pairs, the last yaw replaced by a roll at the wrist."""


def arm_urdf(joints: tuple[tuple[str, float], ...] = ARM7_JOINTS, name: str = "arm7") -> str:
    """URDF text of a spatial arm built from primitives (not shipped anywhere): revolute joints (limits +-2.6 rad,
    2 rad/s) of ``joints`` (axis, height [m] above the previous joint, along z at the neutral pose), a 0.1 m tool to
    the hand frame ``tool0``, a 4 cm cylinder along each link. The default is a 7-joint arm of about a Panda's reach
    (0.94 m from the first joint)."""
    parts = ['<?xml version="1.0"?>', f'<robot name="{name}">', '  <link name="base">',
             '    <collision><origin xyz="0 0 0.1"/><geometry><cylinder radius="0.06" length="0.2"/></geometry>'
             '</collision>', "  </link>"]
    parent = "base"
    for k, (axis, height) in enumerate(joints):
        child = f"link{k + 1}"
        length = joints[k + 1][1] if k + 1 < len(joints) else 0.1
        parts += [f'  <joint name="joint{k + 1}" type="revolute"><parent link="{parent}"/><child link="{child}"/>',
                  f'    <origin xyz="0 0 {height}"/><axis xyz="{axis}"/>',
                  '    <limit lower="-2.6" upper="2.6" effort="50" velocity="2.0"/></joint>',
                  f'  <link name="{child}">']
        if length > 0:
            parts.append(f'    <collision><origin xyz="0 0 {length / 2}"/><geometry><cylinder radius="0.04" '
                         f'length="{length}"/></geometry></collision>')
        parts.append("  </link>")
        parent = child
    parts += [f'  <joint name="tool" type="fixed"><parent link="{parent}"/><child link="tool0"/>',
              '    <origin xyz="0 0 0.1"/></joint>', '  <link name="tool0"/>', "</robot>"]
    return "\n".join(parts) + "\n"


def interruptible() -> None:
    """``subprocess.Popen(..., preexec_fn=interruptible)``: the child starts with SIGINT at its default, as under a
    terminal's Ctrl-C. A session started as a background job of a non-interactive shell (``pytest &`` in a script)
    has SIGINT ignored, every child inherits that through ``exec``, and a Python started so never raises
    ``KeyboardInterrupt``: a test of Ctrl-C would then wait for an interrupt that cannot come."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
