"""Tests of the curated public API (:mod:`previewctl`): one import for a first run, and a light one."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

import previewctl as pc


def test_every_public_name_resolves_and_is_documented() -> None:
    for name in pc.__all__:
        obj = getattr(pc, name)
        assert obj is not None
        if callable(obj):
            assert obj.__doc__, f"previewctl.{name} has no docstring"


def test_a_first_run_needs_one_import() -> None:
    """The package docstring's loop: planar4 along a line past a disc with multi-preview control."""
    robot = pc.load_robot("planar4")
    path = pc.HandPath([[1.9069, 1.0417], [0.80, 1.60]], duration=8.0)
    scene = pc.Scene((pc.Obstacle("disc", pc.Cylinder(0.1, 0.4), pc.Static([0.55, 1.80, 0.0])),))
    ctrl = pc.make_controller("multi", robot=robot, path=path, scene=scene, seed=0)
    q, dt = np.array([0.6, 1.0, -1.2, -1.0]), 0.01
    for k in range(50):
        qdot = ctrl.step(q, k * dt)
        q = pc.integrate(robot, q, qdot, dt)
    assert ctrl.last_info.hand_error < 1e-3
    assert ctrl.last_info.targets is not None and ctrl.last_info.targets.shape == (3, 4)


def test_importing_the_package_does_not_load_matplotlib() -> None:
    code = "import sys, previewctl; print(sorted(m for m in sys.modules if m.split('.')[0] == 'matplotlib'))"
    root = Path(__file__).resolve().parent.parent
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=root).stdout
    assert out.strip() == "[]"
