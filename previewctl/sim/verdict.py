"""A run's verdict in words, from its summary (:meth:`~previewctl.sim.log.RunResult.summary`)."""

from __future__ import annotations

from typing import Any


def verdict_text(summary: dict[str, Any], digits: int = 3) -> str:
    """``"yes"``, or ``"NO: "`` and what failed first, from a run's summary (times with ``digits`` decimals)."""
    if summary["success"]:
        return "yes"
    parts = []
    if summary["collided"]:
        parts.append(f"collision at t = {summary['collision_time']:.{digits}f} s ({summary['collision_link']})")
    if summary.get("self_collided"):
        parts.append(self_collision_text(summary, digits))
    if summary["error_time"] is not None:
        parts.append(f"hand error > {summary['tolerance'] * 1e3:.2f} mm from t = {summary['error_time']:.{digits}f} s")
    return "NO: " + "; ".join(parts)


def self_collision_text(summary: dict[str, Any], digits: int = 2) -> str:
    """``"self-collision at t = 5.40 s: panda_link1 hits panda_leftfinger"`` from a run's summary (which must have
    ``self_collided``)."""
    a, b = summary["self_collision_links"] or ("?", "?")
    return f"self-collision at t = {summary['self_collision_time']:.{digits}f} s: {a} hits {b}"
