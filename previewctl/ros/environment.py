"""Loopback-only ROS 2: the environment that keeps every DDS packet on this machine, set before ROS starts.

:func:`loopback_environment` sets, in ``os.environ``:

* ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``: discovery only among this machine's participants (unicast to
  127.0.0.1, no multicast);
* ``ROS_DOMAIN_ID``: the domain, so that runs side by side (tests) do not see each other;
* ``RMW_IMPLEMENTATION=rmw_fastrtps_cpp`` and ``FASTDDS_DEFAULT_PROFILES_FILE``: Fast DDS with the profile shipped
  with the package (:data:`PROFILE`), whose transports are shared memory and UDPv4 bound to 127.0.0.1 only.

What it leaves, as measured with ``strace`` on the Kilted wheels (Fast DDS 3.2, rmw_fastrtps 9.3): every receiving
socket is bound to 127.0.0.1 and every datagram sent goes to 127.0.0.1; under ``LOCALHOST`` the participant still
opens two idle send sockets (bound to 0.0.0.0 and to each other interface's address) that send nothing
(docs/guide/ros.md, "Nothing leaves the machine").

The variables are read once, when ROS starts (``rclpy.init``); set later, they would silently not apply, so
:func:`loopback_environment` refuses to run then.
"""

from __future__ import annotations

import os
import sys
from importlib import resources
from pathlib import Path

from previewctl.errors import RosError

PROFILE = Path(str(resources.files("previewctl").joinpath("ros", "loopback.xml")))
"""The loopback-only Fast DDS profile shipped with the package."""
DOMAIN_IDS = range(0, 102)
"""The ROS domain IDs valid on every platform (0-101: their DDS ports stay below the ephemeral range)."""


def loopback_environment(domain_id: int) -> dict[str, str]:
    """Set the loopback-only ROS environment (module docstring) in ``os.environ``; call it before ``rclpy.init``.

    Args:
        domain_id: the ROS domain, in 0-101 (a random one per test run keeps runs side by side apart).

    Returns:
        The variables set and their values.

    Raises:
        RosError: ``domain_id`` not an integer in 0-101, or ROS already started in this process (``rclpy.ok()``):
            the variables would not apply.
    """
    if isinstance(domain_id, bool) or not isinstance(domain_id, int) or domain_id not in DOMAIN_IDS:
        raise RosError(f"domain_id must be an integer in 0-101, got {domain_id!r}")
    rclpy = sys.modules.get("rclpy")
    if rclpy is not None and rclpy.ok():
        raise RosError("ROS is already running in this process (rclpy.init was called): set the loopback "
                       "environment before it, or it does not apply")
    variables = {
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "ROS_DOMAIN_ID": str(domain_id),
        "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
        "FASTDDS_DEFAULT_PROFILES_FILE": str(PROFILE),
    }
    os.environ.update(variables)
    return variables


def loopback_in_force() -> bool:
    """Whether ``os.environ`` holds the loopback-only settings of :func:`loopback_environment` (any domain)."""
    env = os.environ
    return (env.get("ROS_AUTOMATIC_DISCOVERY_RANGE") == "LOCALHOST" and env.get("ROS_DOMAIN_ID", "").isdigit()
            and env.get("RMW_IMPLEMENTATION") == "rmw_fastrtps_cpp"
            and env.get("FASTDDS_DEFAULT_PROFILES_FILE") == str(PROFILE))
