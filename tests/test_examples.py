"""The examples in ``examples/`` run as a user runs them and do what they say.

The planar and URDF runs last past the time plain tracking would hit their obstacle (4.3 s and 3.6 s),
so they check the avoidance too; the Panda run is cut to 1 s (its ball arrives at 3.65 s).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
LINE = re.compile(r"max hand error ([0-9.]+) mm, min clearance (-?[0-9]+) mm, collided: (True|False)")


@pytest.mark.parametrize(
    ("script", "duration"),
    [("planar_static_disc.py", 5.0), ("panda_moving_ball.py", 1.0), ("urdf_arm.py", 4.0)],
)
def test_example_runs_and_tracks_the_hand_without_collision(script: str, duration: float) -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}  # this checkout's previewctl, installed or not
    done = subprocess.run(
        [sys.executable, str(ROOT / "examples" / script), "--duration", str(duration)],
        capture_output=True, text=True, env=env, cwd=ROOT, timeout=300,
    )
    assert done.returncode == 0, done.stderr
    match = LINE.search(done.stdout)
    assert match, done.stdout
    error_mm, clearance_mm, collided = float(match[1]), int(match[2]), match[3]
    assert error_mm < 2.0 and clearance_mm > 0 and collided == "False", done.stdout
    assert f"{duration:g} s" in done.stdout
