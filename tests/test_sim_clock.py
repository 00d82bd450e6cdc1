"""Tests of :mod:`previewctl.sim.clock`: simulated ticks, and wall-clock deadlines without drift or catch-up (on a
stand-in clock, so that a loaded host cannot move the deadlines, and once on the real one)."""

from __future__ import annotations

import time

import pytest

import previewctl.sim.clock as clock
from previewctl.sim.clock import Tick, simulated_ticks, wall_ticks


class FakeTime:
    """A stand-in for the ``time`` module: ``sleep`` advances the clock, and every reading takes 1 µs."""

    def __init__(self) -> None:
        self.now = 100.0

    def perf_counter(self) -> float:
        self.now += 1e-6
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds


@pytest.fixture
def fake(monkeypatch: pytest.MonkeyPatch) -> FakeTime:
    stand_in = FakeTime()
    monkeypatch.setattr(clock, "time", stand_in)
    return stand_in


def test_simulated_ticks_are_every_deadline_at_its_own_time() -> None:
    ticks = list(simulated_ticks(0.01, 3))
    assert ticks == [Tick(0, 0.0, 0.01), Tick(1, 0.01, 0.01), Tick(2, 0.02, 0.01), Tick(3, 0.03, 0.01)]


def test_short_cycles_wake_at_every_deadline_without_drift(fake: FakeTime) -> None:
    ticks = []
    for tick in wall_ticks(0.004, 250):
        ticks.append(tick)
        fake.now += 0.001  # the cycle's work
    assert [tick.k for tick in ticks] == list(range(251))
    for tick in ticks[1:]:
        assert 0.0 <= tick.late < 1e-4 and tick.t == pytest.approx(tick.k * 0.004, abs=1e-4)  # no drift
    assert sum(tick.elapsed for tick in ticks[1:]) == pytest.approx(ticks[-1].t)  # the elapsed periods tile time


def test_an_overrun_skips_the_deadlines_it_passed_without_a_burst(fake: FakeTime) -> None:
    ticks = wall_ticks(0.01, 10)
    assert next(ticks).k == 0
    fake.now += 0.035  # the cycle overruns three deadlines
    late = next(ticks)
    assert late.k == 4 and late.t == pytest.approx(0.04, abs=1e-4)  # the first deadline still ahead
    assert late.elapsed == pytest.approx(0.04, abs=1e-4)  # the previous command was applied all that time
    assert next(ticks).k == 5  # then on the grid again: no catching up


def test_a_cycle_past_the_last_deadline_ends_the_run_there(fake: FakeTime) -> None:
    ticks = wall_ticks(0.01, 2)
    next(ticks)
    fake.now += 0.05
    last = next(ticks)
    assert last.k == 2 and last.t >= 0.05 and list(ticks) == []


def test_the_real_clock_waits_for_each_deadline() -> None:
    start = time.perf_counter()
    ticks = list(wall_ticks(0.02, 5))
    assert time.perf_counter() - start >= 0.1 and ticks[-1].k == 5
    assert all(tick.t >= tick.k * 0.02 for tick in ticks)


class Rehearsal:
    """A stand-in for ``Controller.rehearse`` that costs ``cost`` [s] of the stand-in clock per call."""

    def __init__(self, fake: FakeTime, cost: float) -> None:
        self.fake, self.cost, self.calls = fake, cost, 0

    def __call__(self) -> None:
        self.calls += 1
        self.fake.now += self.cost


def test_a_rehearsal_fills_the_last_stretch_and_never_runs_past_the_deadline(fake: FakeTime) -> None:
    rehearse = Rehearsal(fake, 4e-4)
    deadline = fake.now + 0.004
    longest = clock.wait_until(deadline, rehearse, lead=0.0015)
    # from 1.5 ms before the deadline, calls of 0.4 ms while one more (and the 0.2 ms spin) fits: 3 calls
    assert rehearse.calls == 3 and longest == pytest.approx(4e-4, abs=1e-5)
    assert deadline <= fake.now < deadline + 1e-5


def test_a_rehearsal_expected_to_be_too_long_is_skipped_then_tried_again(fake: FakeTime) -> None:
    rehearse = Rehearsal(fake, 4e-4)
    deadline = fake.now + 0.004
    assert clock.wait_until(deadline, rehearse, lead=0.0015, expected=0.002) == pytest.approx(0.001)
    assert rehearse.calls == 0 and deadline <= fake.now < deadline + 1e-5
    deadline = fake.now + 0.004
    clock.wait_until(deadline, rehearse, lead=0.0015, expected=0.001)  # the halved guess fits: it runs again
    assert rehearse.calls == 1


def test_without_a_rehearsal_the_clock_sleeps_to_the_spin(fake: FakeTime) -> None:
    deadline = fake.now + 0.004
    assert clock.wait_until(deadline) == 0.0 and deadline <= fake.now < deadline + 1e-5


def test_wall_ticks_rehearse_over_the_last_half_of_each_period(fake: FakeTime) -> None:
    rehearse = Rehearsal(fake, 1e-4)
    ticks = []
    for tick in wall_ticks(0.001, 10, rehearse):  # 1 kHz: the last 0.5 ms of each period
        ticks.append(tick)
        fake.now += 1e-4  # the cycle's work
    assert [tick.k for tick in ticks] == list(range(11)) and all(0.0 <= tick.late < 1e-4 for tick in ticks)
    # per wait: from 0.5 ms before the deadline, 0.1 ms calls while one more and the 0.2 ms spin fit: 2 each, 10 waits
    assert rehearse.calls == 20
