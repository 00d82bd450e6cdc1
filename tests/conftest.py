"""Shared fixtures and test settings: the robots (loaded once per session) and the Hypothesis profiles.

Hypothesis profiles (choose one with ``HYPOTHESIS_PROFILE=<name>``):

* ``ci`` (the default, everywhere): derandomized, so every run of the suite tries the same examples
  and a failure in CI reproduces on any machine; no example database, no deadline (a shared host
  stalls).
* ``explore``: fresh random examples on every run, for hunting new counter-examples after touching
  geometry or kinematics; Hypothesis's example database (``.hypothesis/``) replays a counter-example
  it found until it is fixed, and a failure prints the ``@reproduce_failure`` blob to pin it.

Per-test ``@settings(...)`` (example counts) inherit the rest from the loaded profile, because this
file is imported before the test modules.

Plain helper functions (``rot_z``, ``planar_doc``, ``random_chain_urdf``) live in ``helpers.py``.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest
from hypothesis import settings

import previewctl
from previewctl.robot.model import Robot

settings.register_profile("ci", derandomize=True, database=None, deadline=None, print_blob=True)
settings.register_profile("explore", deadline=None, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture(scope="session", autouse=True)
def private_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """The self-pair screens (:mod:`previewctl.robot.self_pairs`) cache into a folder of this session, not the
    user's ``~/.cache`` (subprocesses inherit it)."""
    patch = pytest.MonkeyPatch()
    patch.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("cache")))
    yield
    patch.undo()


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
