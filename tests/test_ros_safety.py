"""The parts of the ROS node that need no ROS: :mod:`previewctl.ros.safety`, its settings, its environment, and
``previewctl ros`` without the ``[ros]`` extra (these run in every install)."""

from __future__ import annotations

import importlib
import os
import re
from types import ModuleType

import numpy as np
import pytest

from previewctl.cli.common import ExitCode
from previewctl.cli.main import main
from previewctl.errors import PlanningWorkerError, RosError
from previewctl.ros.environment import PROFILE, loopback_environment, loopback_in_force
from previewctl.ros.safety import stop_reason, within_limits
from previewctl.ros.settings import NodeSettings

PERIOD = 0.02


@pytest.mark.parametrize(("age", "error", "worker", "reason"), [
    (None, 0.0, None, "no joint state yet"),
    (0.061, 0.0, None, r"joint states stale: the last is 0.061 s old, more than 3 periods \(0.060 s\)"),
    (0.059, 0.051, None, "hand error 0.0510 m exceeds max_hand_error 0.05 m"),
    (0.0, float("nan"), None, "hand error nan m exceeds"),
    (0.0, 0.0, PlanningWorkerError("worker died"), "planning worker failed: worker died"),
])
def test_each_stop_names_its_reason(age: float | None, error: float, worker: PlanningWorkerError | None,
                                    reason: str) -> None:
    got = stop_reason(age, PERIOD, 3.0, error, 0.05, worker)
    assert got is not None
    assert re.match(reason, got), got


def test_a_fresh_state_on_the_path_does_not_stop() -> None:
    assert stop_reason(0.06, PERIOD, 3.0, 0.05, 0.05, None) is None  # both at their limit: still running


def test_a_command_is_scaled_as_a_whole_to_the_limits() -> None:
    limits = np.array([1.0, 2.0, np.inf])
    qdot, note = within_limits(np.array([2.0, -1.0, 30.0]), limits)
    np.testing.assert_allclose(qdot, [1.0, -0.5, 15.0])  # direction kept, the worst joint at its limit
    assert note == "command scaled by 1/2 to the speed limits"
    same, none = within_limits(np.array([0.5, -2.0, 1e6]), limits)
    np.testing.assert_array_equal(same, [0.5, -2.0, 1e6])
    assert none is None


def test_a_command_that_is_not_finite_becomes_zero() -> None:
    qdot, note = within_limits(np.array([0.1, np.nan]), np.ones(2))
    np.testing.assert_array_equal(qdot, [0.0, 0.0])
    assert note == "command not finite: [0.1, nan]"


def test_settings_need_a_scenario_or_a_robot_with_a_path() -> None:
    with pytest.raises(RosError, match=r"needs a scenario file .* or a robot and its hand path"):
        NodeSettings()
    with pytest.raises(RosError, match=r"scenario .a.toml. and robot .panda. / waypoints both given"):
        NodeSettings(scenario="a.toml", robot="panda")
    with pytest.raises(RosError, match="rate"):
        NodeSettings(scenario="a.toml", rate=0.0)
    with pytest.raises(RosError, match="velocity_scale"):
        NodeSettings(scenario="a.toml", velocity_scale=1.5)
    assert NodeSettings(scenario="a.toml", rate=50).period == pytest.approx(0.02)


def test_loopback_environment_sets_every_variable(monkeypatch: pytest.MonkeyPatch) -> None:
    for key in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_DOMAIN_ID", "RMW_IMPLEMENTATION",
                "FASTDDS_DEFAULT_PROFILES_FILE"):
        monkeypatch.delenv(key, raising=False)
    assert not loopback_in_force()
    assert loopback_environment(7) == {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_DOMAIN_ID": "7",
                                       "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
                                       "FASTDDS_DEFAULT_PROFILES_FILE": str(PROFILE)}
    assert loopback_in_force() and os.environ["ROS_DOMAIN_ID"] == "7" and PROFILE.is_file()
    for bad in (-1, 102, True, 3.0):
        with pytest.raises(RosError, match=f"domain_id must be an integer in 0-101, got {bad!r}"):
            loopback_environment(bad)  # type: ignore[arg-type]


def test_ros_without_the_extra_names_it(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    real = importlib.import_module

    def without_rclpy(name: str, package: str | None = None) -> ModuleType:
        if name.split(".")[0] == "rclpy":
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return real(name, package)

    monkeypatch.setattr(importlib, "import_module", without_rclpy)
    assert main(["ros", "--params-file", "x.yaml"]) == ExitCode.USAGE
    assert capsys.readouterr().err == ("previewctl: error: previewctl ros needs rclpy, which is not installed: "
                                       "pip install 'previewctl[ros]'\n")
