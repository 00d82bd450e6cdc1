"""Shared fixtures: the robots (loaded once per session) and a random serial-chain URDF generator."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import strategies as st

import previewctl
from previewctl.robot.model import Robot

# A hypothesis ``draw`` function, or a seeded numpy generator.
Source = np.random.Generator | Callable[[st.SearchStrategy[Any]], Any]


@pytest.fixture(scope="session")
def planar4() -> Robot:
    """The paper's planar 4-link arm (shipped)."""
    return previewctl.load_robot("planar4")


@pytest.fixture(scope="session")
def panda() -> Robot:
    """Franka Panda from example-robot-data (fingers locked)."""
    return previewctl.load_robot("panda")


@pytest.fixture(scope="session")
def ur5() -> Robot:
    """UR5 from example-robot-data."""
    return previewctl.load_robot("ur5")


@pytest.fixture(scope="session")
def panda_mesh() -> Robot:
    """Panda with its exact (BVH) collision meshes (``geometry="mesh"``)."""
    return previewctl.load_robot("panda", geometry="mesh")


@pytest.fixture(scope="session")
def kinova() -> Robot:
    """Kinova Jaco 2: continuous joints, so nq = 9 and nv = 6."""
    return previewctl.load_robot("kinova")


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
