"""Tests of :mod:`previewctl.sim.clock`: simulated ticks, and wall-clock deadlines without drift or catch-up."""

from __future__ import annotations

import time

import pytest

from previewctl.sim.clock import Tick, simulated_ticks, wall_ticks


def test_simulated_ticks_are_every_deadline_at_its_own_time() -> None:
    ticks = list(simulated_ticks(0.01, 3))
    assert ticks == [Tick(0, 0.0, 0.01), Tick(1, 0.01, 0.01), Tick(2, 0.02, 0.01), Tick(3, 0.03, 0.01)]


def test_wall_ticks_wait_for_each_deadline_and_time_is_the_wall_time() -> None:
    start = time.perf_counter()
    ticks = list(wall_ticks(0.01, 10))
    wall = time.perf_counter() - start
    assert [tick.k for tick in ticks] == list(range(11))
    for tick in ticks:
        assert tick.t >= tick.k * 0.01 and tick.late == pytest.approx(tick.t - tick.k * 0.01)
    assert wall >= 0.1  # it waited for the last deadline
    assert sum(tick.elapsed for tick in ticks[1:]) == pytest.approx(ticks[-1].t)  # the elapsed periods tile time


def test_an_overrun_skips_the_deadlines_it_passed_without_a_burst() -> None:
    ticks = wall_ticks(0.01, 10)
    assert next(ticks).k == 0
    time.sleep(0.035)  # the cycle overruns three deadlines
    late = next(ticks)
    assert late.k >= 4 and late.elapsed >= 0.035  # the next deadline ahead, and the whole time it took
    after = next(ticks)
    assert after.k == late.k + 1 and after.t >= after.k * 0.01  # then on the grid again: no catching up
    assert list(ticks)[-1].k == 10


def test_a_cycle_past_the_last_deadline_ends_the_run_there() -> None:
    ticks = wall_ticks(0.01, 2)
    next(ticks)
    time.sleep(0.05)
    last = next(ticks)
    assert last.k == 2 and last.t >= 0.05 and list(ticks) == []
