"""Shared fixtures: the robots, loaded once per session.

Plain helper functions (``rot_z``, ``planar_doc``, ``random_chain_urdf``) live in ``helpers.py``.
"""

from __future__ import annotations

import pytest

import previewctl
from previewctl.robot.model import Robot


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
