"""Tests of :mod:`previewctl.control.background` and :mod:`previewctl.control.worker`: planning beside the loop.

The worker is a spawned process, so the stand-ins it runs (a search, a computation that waits on an event) are
module-level classes: the worker imports this module to unpickle them. No assertion is on speed; the waits for the
worker have generous timeouts (its start imports the package, which takes seconds on a loaded host).
"""

from __future__ import annotations

import gc
import multiprocessing
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers import interruptible
from numpy.typing import NDArray

import previewctl as pc
from previewctl.control.background import (
    FIFO_REFUSED,
    LOOP_PRIORITY,
    WAKE_LATENCY_FILE,
    WAKE_REFUSED,
    BackgroundOptions,
    PlanningResult,
    PlanningSide,
    RealTimeGrants,
    answer,
    prompt_wake_up,
    real_time_priority,
    worker_cores,
)
from previewctl.control.planner import PlanTiming, WindowPlanner
from previewctl.index.evaluator import Evaluator
from previewctl.robot.model import Robot
from previewctl.search.reachability import ReachMotion
from previewctl.sim.scenario import Scenario

Array = NDArray[np.float64]
Q0 = [0.6, 1.0, -1.2, -1.0]  # [rad]; the hand at START
TARGET = [0.9, 0.7, -1.4, -0.7]  # [rad]; the stand-in searches' answer, away from Q0
START, END = [1.9069, 1.0417], [1.6069, 0.6417]  # [m]
DT = 0.004  # [s]
WAIT = 180.0  # [s] of wall time the worker may take to start and answer on a loaded host


def planar_scenario(controller: str = "multi", **params: Any) -> Scenario:
    """planar4 along a 0.5 m line, a ball near link 2 (as in test_control_controller.py)."""
    return pc.scenario_from_dict({
        "name": "background_test",
        "robot": {"source": "planar4", "q0": Q0},
        "path": {"waypoints": [START, END], "duration": 5.0},
        "obstacles": [{"name": "ball", "shape": "sphere", "radius": 0.15, "position": [1.0, 0.6]}],
        "controller": {"name": controller, **params},
        "timing": {"duration": 1.0},
    })


@dataclass(frozen=True)
class Best:
    q: Array
    S: float


class FixedSearch:
    """A stand-in for the 1-step GA: always the configuration TARGET."""

    def __init__(self) -> None:
        self.best = Best(np.array(TARGET), 1.0)

    def step(self, target: Array, t: float) -> Best:
        return self.best

    def peaks(self) -> tuple[Best, ...]:
        return (self.best,)

    def seed(self, q: Array) -> None:
        pass


def fixed_search(i: int, rng: np.random.Generator) -> FixedSearch:
    return FixedSearch()


class Held:
    """The worker's computation, held while ``go`` is clear (the test holds it); ``blocked`` is 1 while it waits."""

    def __init__(self) -> None:
        context = multiprocessing.get_context("spawn")
        self.go, self.blocked = context.Event(), context.Value("i", 0)
        self.go.set()

    def __call__(self, side: PlanningSide, q: Array, t: float) -> PlanningResult | None:
        if not self.go.is_set():
            self.blocked.value = 1
            self.go.wait()
            self.blocked.value = 0
        return answer(side, q, t)


def stand_in_controller(**kwargs: Any) -> pc.Controller:
    """``multi`` with argmax imaginary arms on stand-in searches, planning in the background."""
    return pc.make_controller(planar_scenario("multi", coherent=False), search_factory=fixed_search,
                              planning="background", **kwargs)


def step_until(ctrl: pc.Controller, k: int, q: Array, done: Callable[[pc.ControlInfo], bool]) -> int:
    """Step at ``t = k DT`` (the arm held at ``q``), 10 ms of wall time apart, until ``done(last_info)``; the next
    ``k``."""
    deadline = time.monotonic() + WAIT
    while True:
        ctrl.step(q, k * DT, DT)
        k += 1
        if done(ctrl.last_info):
            return k
        assert time.monotonic() < deadline, f"no change after {WAIT} s: {ctrl.last_info}"
        time.sleep(0.01)


def gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


# ------------------------------------------------------------------------------------------- the choice


def test_background_is_recorded_and_inline_stays_the_default() -> None:
    assert pc.make_controller(planar_scenario("multi")).describe().planning == "inline"
    with stand_in_controller() as ctrl:
        assert ctrl.describe().planning == "background"
        assert "planning background" in str(ctrl.describe())


def test_bad_planning_choices_name_the_valid_ones() -> None:
    with pytest.raises(pc.UnknownNameError, match="unknown planning 'beside'; valid: inline, background"):
        pc.make_controller(planar_scenario("multi"), planning="beside")
    with pytest.raises(pc.ParameterError, match="'gradient' cannot plan in the background; valid: single, multi"):
        pc.make_controller(planar_scenario("gradient"), planning="background")
    with pytest.raises(pc.ParameterError, match="reach plans in the background only with its planner"):
        pc.make_controller(planar_scenario("reach", coherent=False), planning="background")
    with pytest.raises(pc.ParameterError, match=r"plan_latency = 'measured' stands in for planning beside the loop"):
        pc.make_controller(planar_scenario("multi", plan_latency="measured"), planning="background")
    with pytest.raises(pc.ParameterError, match="niceness"):
        BackgroundOptions(niceness=20)
    with pytest.raises(pc.ParameterError, match="search_niceness"):
        BackgroundOptions(search_niceness=-1)
    with pytest.raises(pc.ParameterError, match="timeout"):
        BackgroundOptions(timeout=0.0)


# ---------------------------------------------------------------------------------- never waits, falls back


def test_step_never_waits_for_a_held_worker_and_falls_back_to_qp() -> None:
    qp = pc.make_controller(planar_scenario("qp"))
    held, q = Held(), np.array(Q0)
    with stand_in_controller(worker_compute=held) as ctrl:
        k = step_until(ctrl, 0, q, lambda info: not info.fallback)
        np.testing.assert_array_equal(ctrl.last_info.targets, [TARGET] * 3)  # the worker's imaginary arms
        held.go.clear()
        k = step_until(ctrl, k, q, lambda info: held.blocked.value == 1)  # the worker holds a state
        worker = ctrl.planning.worker  # type: ignore[union-attr]
        answered = worker.answered
        start, ages, fallbacks = time.perf_counter(), [], []
        for _ in range(200):
            qdot = ctrl.step(q, k * DT, DT)
            info = ctrl.last_info
            ages.append(info.plan_age)
            fallbacks.append(info.fallback)
            if info.fallback:  # the qp law: v = 0, the same command as the qp controller's
                np.testing.assert_allclose(qdot, qp.step(q, k * DT, DT), atol=1e-9)
            k += 1
        assert time.perf_counter() - start < 5.0  # 200 steps; waiting once for the worker would take forever
        assert np.all(np.diff(ages) > 0)  # the same result, older and older
        valid = BackgroundOptions().arms_valid_frames * ctrl.frame
        assert fallbacks == [age > valid + 1e-9 for age in ages] and fallbacks[-1]
        assert ctrl.last_info.worker_error is None  # held, not hung: within the timeout
        assert worker.answered == answered  # the state it holds is not answered yet
        held.go.set()
        step_until(ctrl, k, q, lambda info: not info.fallback)
        assert worker.answered > answered
        assert ctrl.last_info.plan_age is not None and ctrl.last_info.plan_age <= valid


def test_a_rehearsal_takes_no_answer_and_sends_no_state() -> None:
    held, q = Held(), np.array(Q0)
    with stand_in_controller(worker_compute=held) as ctrl:
        k = step_until(ctrl, 0, q, lambda info: not info.fallback)
        held.go.clear()
        k = step_until(ctrl, k, q, lambda info: held.blocked.value == 1)  # the worker holds a state
        worker = ctrl.planning.worker  # type: ignore[union-attr]
        k = step_until(ctrl, k, q, lambda info: worker.waiting)  # and a newer one waits in the loop's slot
        answered, info = worker.answered, ctrl.last_info
        held.go.set()
        start = time.monotonic()
        while time.monotonic() - start < 1.0:  # the answer comes meanwhile; rehearsals must leave it in the pipe
            ctrl.rehearse()
        assert worker.answered == answered and worker.busy and worker.waiting and ctrl.last_info is info
        step_until(ctrl, k, q, lambda info: worker.answered > answered)  # a rehearsal that took it: no more answers
        assert not worker.waiting  # the state in the slot went out once the answer came
    ctrl.rehearse()  # closed: nothing to rehearse, no error


@pytest.mark.skipif(not Path("/proc/self/environ").is_file(), reason="reads a process's environment from /proc")
def test_the_worker_runs_one_blas_thread_and_the_loop_keeps_its_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    from previewctl.control.worker import SINGLE_THREAD

    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    before = dict(os.environ)
    with stand_in_controller() as ctrl:
        pid = ctrl.planning.worker.pid  # type: ignore[union-attr]
        # read once it answers: just after the spawn the child may not have exec'd yet (its environ reads empty)
        step_until(ctrl, 0, np.array(Q0), lambda info: not info.fallback)
        environ = dict(entry.split("=", 1) for entry in
                       Path(f"/proc/{pid}/environ").read_text().split("\0") if "=" in entry)
        assert dict(os.environ) == before
    assert {name: environ.get(name) for name in SINGLE_THREAD} == SINGLE_THREAD


def test_a_hung_worker_is_reported_after_the_timeout() -> None:
    held, q = Held(), np.array(Q0)
    with stand_in_controller(worker_compute=held, background=BackgroundOptions(timeout=1.0)) as ctrl:
        k = step_until(ctrl, 0, q, lambda info: not info.fallback)
        held.go.clear()
        step_until(ctrl, k, q, lambda info: info.worker_error is not None)
        assert ctrl.last_info.fallback
        assert isinstance(ctrl.last_info.worker_error, pc.PlanningWorkerError)
        assert "has not answered for more than 1 s" in str(ctrl.last_info.worker_error)
        held.go.set()  # it answers again: the error is gone
        step_until(ctrl, k, q, lambda info: not info.fallback)
        assert ctrl.last_info.worker_error is None


def test_a_killed_worker_is_reported_and_close_leaves_no_child() -> None:
    ctrl = stand_in_controller()
    q = np.array(Q0)
    k = step_until(ctrl, 0, q, lambda info: not info.fallback)
    pid = ctrl.planning.worker.pid  # type: ignore[union-attr]
    assert pid in [child.pid for child in multiprocessing.active_children()]
    os.kill(pid, signal.SIGKILL)
    k = step_until(ctrl, k, q, lambda info: info.worker_error is not None)
    error = ctrl.last_info.worker_error
    assert isinstance(error, pc.PlanningWorkerError) and f"pid {pid}) exited with code -9" in str(error)
    for _ in range(5):  # no hang, and the qp law from now on
        ctrl.step(q, k * DT, DT)
        k += 1
        assert ctrl.last_info.fallback and ctrl.last_info.worker_error is error
    ctrl.close()
    ctrl.close()  # idempotent
    ctrl.step(q, k * DT, DT)
    assert ctrl.last_info.fallback and ctrl.last_info.worker_error is error  # the first error stays
    assert pid not in [child.pid for child in multiprocessing.active_children()]
    assert gone(pid)


def test_close_ends_a_busy_worker_and_a_forgotten_controller_leaves_no_child() -> None:
    held = Held()
    held.go.clear()  # the worker blocks on its first state
    ctrl = stand_in_controller(worker_compute=held)
    step_until(ctrl, 0, np.array(Q0), lambda info: held.blocked.value == 1)
    pid = ctrl.planning.worker.pid  # type: ignore[union-attr]
    ctrl.close()  # asked, then terminated
    assert gone(pid) and pid not in [child.pid for child in multiprocessing.active_children()]
    ctrl.step(np.array(Q0), 1.0, DT)  # stepping a closed controller: the qp law
    assert ctrl.last_info.fallback and "was closed" in str(ctrl.last_info.worker_error)
    forgotten = stand_in_controller()
    pid = forgotten.planning.worker.pid  # type: ignore[union-attr]
    del forgotten  # the finalizer ends the worker
    gc.collect()
    assert gone(pid) and pid not in [child.pid for child in multiprocessing.active_children()]


# --------------------------------------------------------------------------------------- late plans joined


def line_plan(robot: Robot, t0: float) -> tuple[WindowPlanner, ReachMotion]:
    """A window planner and a plan from Q0 at ``t0`` to TARGET one second later."""
    planner = WindowPlanner(robot, Evaluator(robot, pc.Scene()), PlanTiming(replan_period=0.5, window=1.5))
    times = np.array([t0, t0 + 1.0])
    motion = ReachMotion(times=times, q=np.array([Q0, TARGET]), S=np.ones(2), branch=np.zeros(2, dtype=np.int64),
                         cells=np.zeros(2, dtype=np.int64), min_S=1.0, total_S=2.0)
    return planner, motion


def test_a_late_plan_is_joined_to_the_present_state(planar4: Robot) -> None:
    """A plan made from Q0 at t0 = 0 and delivered at t1 = 0.4 s, when the arm is off it by ``offset``."""
    planner, motion = line_plan(planar4, 0.0)
    t1, gain = 0.4, np.full(4, 2.0)
    offset = np.array([0.05, -0.04, 0.03, 0.02])  # [rad]
    q1 = motion.at(t1) + offset  # where the arm is at t1
    planner.follow(motion, t1, q1)
    np.testing.assert_allclose(planner.point(t1)[0], q1, atol=1e-12)  # the joined plan starts at the arm ...
    np.testing.assert_allclose(planner.point(t1)[1], motion.velocity(t1))  # ... with the plan's velocity
    v, q_ref, _ = planner.pull(q1, t1, gain)  # the first command's null-space input after the delivery
    lookahead, period = planner.timing.lookahead, planner.timing.replan_period
    progress = motion.at(t1 + lookahead) - motion.at(t1)
    np.testing.assert_allclose(q_ref - q1, progress, atol=1e-12)  # the plan's progress from where the arm is
    on_plan = motion.velocity(t1 + lookahead) + gain * progress  # the command of an arm on the plan
    np.testing.assert_allclose(v, on_plan, atol=1e-12)
    # without the join: a jump of K * offset toward the plan; followed from its own start: back toward Q0
    unjoined = on_plan - gain * offset
    naive = motion.velocity(lookahead) + gain * (motion.at(lookahead) - q1)
    assert np.dot(naive - on_plan, np.array(Q0) - q1) > 0.1 and np.linalg.norm(unjoined - on_plan) > 0.1
    # the offset fades after the lookahead, over one replan period; then the joined plan is the plan
    middle = t1 + lookahead + period / 2
    np.testing.assert_allclose(planner.point(middle)[0], motion.at(middle) + offset / 2, atol=1e-12)
    np.testing.assert_allclose(planner.point(middle)[1], motion.velocity(middle) - 1.5 / period * offset, atol=1e-12)
    after = t1 + lookahead + period
    np.testing.assert_allclose(planner.point(after)[0], motion.at(after), atol=1e-12)
    np.testing.assert_allclose(planner.point(after + 0.1)[1], motion.velocity(after + 0.1))


# ------------------------------------------------------------------------------------------ a real run


@pytest.mark.parametrize(("name", "targets"), [("multi", 3), ("reach", 3), ("horizon", 1)])
def test_a_real_background_run_uses_the_workers_plans_and_cleans_up(name: str, targets: int,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """Coherent ``multi`` on planar4 (points of a route: the GA and the DP), ``reach`` (the DP's plan toward the GA's
    peaks) and ``horizon`` (the DP's plan); a rehearsal of the last step posts nothing and keeps the result in use."""
    scenario = planar_scenario(name)
    apart = BackgroundOptions(plans_apart=True)  # the default on 4 cores or more (test below)
    with pc.make_controller(scenario, planning="background", background=apart) as ctrl:
        assert ctrl.describe().planner == "dp" and ctrl.describe().planning == "background"
        pid = ctrl.planning.worker.pid  # type: ignore[union-attr]
        plans = ctrl.planning.plans  # type: ignore[union-attr]
        assert (plans is None) == (name == "horizon")  # a route's plans in a worker of their own
        pids = [pid] if plans is None else [pid, plans.pid]
        q, k, robot = np.array(scenario.q0), 0, scenario.robot
        deadline = time.monotonic() + WAIT
        used = 0
        while used == 0 or (plans is not None and ctrl.planning.searched is None):  # type: ignore[union-attr]
            qdot = ctrl.step(q, k * DT, DT)
            q = pc.integrate(robot, q, qdot, DT)
            k += 1
            info = ctrl.last_info
            assert info.worker_error is None and info.hand_error < 1e-3
            used += not info.fallback
            assert time.monotonic() < deadline, f"no valid plan after {WAIT} s: {info}"
            time.sleep(0.02)  # the path's clock runs 6 times slower than the wall's: the host is shared
        assert info.plan_age is not None and info.targets is not None and info.targets.shape == (targets, 4)
        result = ctrl.planning.result  # type: ignore[union-attr]
        with monkeypatch.context() as patch:
            for worker in (ctrl.planning.worker, plans):  # type: ignore[union-attr]
                if worker is not None:
                    patch.setattr(worker, "post", lambda *state: pytest.fail(f"a rehearsal posted {state}"))
            ctrl.rehearse()
        assert ctrl.last_info is info and ctrl.planning.result is result  # type: ignore[union-attr]
        options, own = BackgroundOptions(), os.getpriority(os.PRIO_PROCESS, 0)
        if plans is not None:  # the searches answer apart from the plans: their peaks are the plans' goals
            searched = ctrl.planning.searched  # type: ignore[union-attr]
            assert searched is not None and searched.peaks is not None and len(searched.peaks) == targets
            assert os.getpriority(os.PRIO_PROCESS, plans.pid) == min(19, own + options.niceness)
            assert os.getpriority(os.PRIO_PROCESS, pid) == min(19, own + options.niceness + options.search_niceness)
        else:
            assert os.getpriority(os.PRIO_PROCESS, pid) == min(19, own + options.niceness)
        if hasattr(os, "sched_getaffinity"):  # the workers leave the loop one core
            loop = os.sched_getaffinity(0)
            kept = loop - {min(loop)} if len(loop) >= 2 else loop
            assert [os.sched_getaffinity(p) for p in pids] == [kept] * len(pids)
    assert all(gone(p) for p in pids) and not multiprocessing.active_children()


@pytest.mark.parametrize(("cores", "machine", "kept"), [({0}, 1, None), ({0, 1}, 2, {1}), ({2, 5, 7}, 8, {5, 7}),
                                                       ({3}, 4, {0, 1, 2}), ({1}, 2, {0})])
def test_the_workers_cores_are_the_processs_but_its_lowest(monkeypatch: pytest.MonkeyPatch, cores: set[int],
                                                           machine: int, kept: set[int] | None) -> None:
    """A loop on several cores keeps the lowest; a loop pinned to one keeps it, and the workers take the others."""
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(cores), raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: machine)
    assert worker_cores() == kept


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2,
                    reason="CPU affinity on two cores or more")
def test_without_a_loop_core_the_worker_runs_on_the_loops_cores() -> None:
    with stand_in_controller(background=BackgroundOptions(loop_core=False)) as ctrl:
        assert os.sched_getaffinity(ctrl.planning.worker.pid) == os.sched_getaffinity(0)  # type: ignore[union-attr]
    with stand_in_controller() as ctrl:
        assert os.sched_getaffinity(ctrl.planning.worker.pid) == worker_cores()  # type: ignore[union-attr]


@pytest.mark.skipif(not hasattr(os, "SCHED_RESET_ON_FORK"), reason="Linux scheduling classes")
def test_a_real_time_priority_is_the_threads_alone_and_undone_after() -> None:
    before = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)
    child = [sys.executable, "-c", "import os; print(os.sched_getscheduler(0))"]
    with real_time_priority() as granted:
        inside = (os.sched_getscheduler(0) & ~os.SCHED_RESET_ON_FORK, os.sched_getparam(0).sched_priority)
        started = int(subprocess.run(child, capture_output=True, text=True, check=True).stdout)
    assert (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) == before
    if granted:  # root, CAP_SYS_NICE or an rtprio limit
        assert inside == (os.SCHED_FIFO, LOOP_PRIORITY)
        assert started == os.SCHED_OTHER  # a worker started meanwhile runs in the ordinary class
    else:
        assert inside == before


@pytest.mark.skipif(not hasattr(os, "SCHED_RESET_ON_FORK"), reason="Linux scheduling classes")
def test_a_refused_real_time_priority_changes_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(pid: int, policy: int, param: object) -> None:
        raise PermissionError(1, "Operation not permitted")

    before = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)
    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    with real_time_priority() as granted:
        assert not granted
        assert (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) == before


def _open_files() -> set[str]:
    """The paths this process holds open."""
    return {os.path.realpath(fd) for fd in Path("/proc/self/fd").iterdir() if fd.exists()}


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="Linux's /proc")
def test_the_wake_up_request_is_written_and_held_open_until_the_context_ends(tmp_path: Path) -> None:
    request = tmp_path / "cpu_dma_latency"
    request.write_bytes(b"")
    with prompt_wake_up(str(request)) as awake:
        assert awake
        assert str(request.resolve()) in _open_files()  # the request holds while the file is open
        assert request.read_bytes() == (0).to_bytes(4, sys.byteorder)  # an int32 of 0 µs, in the CPU's own order
    assert str(request.resolve()) not in _open_files()


def test_a_refused_wake_up_request_is_said(tmp_path: Path) -> None:
    with prompt_wake_up(str(tmp_path / "missing" / "cpu_dma_latency")) as awake:
        assert not awake


@pytest.mark.skipif(not Path(WAKE_LATENCY_FILE).exists(), reason="Linux's PM QoS")
def test_the_cpus_wake_up_latency_is_zero_inside_when_granted() -> None:
    with prompt_wake_up() as awake:
        if awake:  # root: the kernel's aggregated request, read back from the device, is 0 µs
            with open(WAKE_LATENCY_FILE, "rb") as device:
                assert int.from_bytes(device.read(4), sys.byteorder) == 0


@pytest.mark.parametrize(("fifo", "awake"), [(True, True), (False, True), (True, False), (False, False)])
def test_a_real_time_loop_says_each_refusal(fifo: bool, awake: bool) -> None:
    refusals = RealTimeGrants(fifo=fifo, awake=awake).refusals
    assert (FIFO_REFUSED in refusals) is not fifo and (WAKE_REFUSED in refusals) is not awake
    assert len(refusals) == (not fifo) + (not awake)


@pytest.mark.parametrize(("cores", "apart"), [(1, False), (2, False), (3, False), (4, True), (16, True)])
def test_plans_run_apart_by_default_on_four_cores_or_more(monkeypatch: pytest.MonkeyPatch, cores: int,
                                                          apart: bool) -> None:
    """The cores the process may run on decide (its affinity, as a container's CPU limit sets it)."""
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(cores)), raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 64)  # the machine's count does not
    assert BackgroundOptions().plans_apart is apart


@pytest.mark.parametrize("name", ["multi", "reach"])
def test_plans_not_apart_run_in_one_worker(name: str) -> None:
    """``plans_apart = False``: one worker makes the generations and the plans (as before the split); its answers
    carry the plan, dated by its start, and the searches' best candidates."""
    scenario = planar_scenario(name)
    with pc.make_controller(scenario, planning="background", background=BackgroundOptions(plans_apart=False)) as ctrl:
        planning = ctrl.planning
        assert planning is not None and planning.plans is None
        k = step_until(ctrl, 0, np.array(Q0), lambda info: not info.fallback)
        result = planning.result  # type: ignore[attr-defined]
        assert result is not None and result.best is not None and result.made <= (k - 1) * DT
        assert ctrl.last_info.targets is not None and ctrl.last_info.targets.shape == (3, 4)
    assert not multiprocessing.active_children()


def test_a_killed_plans_worker_is_reported_and_close_leaves_no_child() -> None:
    """A route's plans' worker killed: its error, the ``qp`` fallback while the searches' worker goes on; ``close()``
    ends both."""
    scenario = planar_scenario("multi")
    q = np.array(Q0)
    ctrl = pc.make_controller(scenario, planning="background", background=BackgroundOptions(plans_apart=True))
    k = step_until(ctrl, 0, q, lambda info: not info.fallback)
    searches, plans = ctrl.planning.worker, ctrl.planning.plans  # type: ignore[union-attr]
    assert plans is not None and plans.pid != searches.pid
    os.kill(plans.pid, signal.SIGKILL)
    k = step_until(ctrl, k, q, lambda info: info.worker_error is not None)
    assert f"pid {plans.pid}) exited with code -9" in str(ctrl.last_info.worker_error) and ctrl.last_info.fallback
    answered = searches.answered
    step_until(ctrl, k, q, lambda info: searches.answered > answered)  # no hang: the searches answer on
    assert ctrl.last_info.fallback and searches.error is None
    ctrl.close()
    assert gone(plans.pid) and gone(searches.pid) and not multiprocessing.active_children()


def test_the_worker_sides_answer_as_inline_planning(planar4: Robot) -> None:
    """Run in this process: the searches' answer and then the plans' on its peaks give the plan the inline route
    policy follows; the one-worker call refuses a part that runs in two."""
    scenario = planar_scenario("multi")
    inline = pc.make_controller(scenario)
    inline.step(np.array(Q0), 0.0, DT)
    from previewctl.control.factory import planning_side

    side = planning_side(replace(scenario.controller), scenario.robot, scenario.path, scenario.scene, scenario.index,
                         scenario.potential, np.random.default_rng(scenario.seed), 0.033, None)
    searched = side.searches(np.array(Q0), 0.0)
    assert searched.peaks is not None and len(searched.peaks) == 3 and searched.frames == 1
    assert searched.motion is None and searched.best is not None
    result = side.plans(np.array(Q0), 0.0, searched.peaks, searched.frames)
    assert result is not None and result.motion is not None and result.made == 0.0 and result.compute > 0
    followed = inline.law.policy.planner.planner.motion  # type: ignore[attr-defined]
    np.testing.assert_array_equal(result.motion.q, followed.q)
    assert side.plans(np.array(Q0), 0.01, searched.peaks, searched.frames) is None  # the same plan: nothing new
    with pytest.raises(pc.ConfigurationError, match=r"run in two workers: searches\(\) and plans\(\)"):
        side(np.array(Q0), 0.02)
    horizon = planning_side(planar_scenario("horizon").controller, scenario.robot, scenario.path, scenario.scene,
                            scenario.index, scenario.potential, np.random.default_rng(0), 0.033, None)
    with pytest.raises(pc.ConfigurationError, match="no searches and planner to run apart: the call answers"):
        horizon.searches(np.array(Q0), 0.0)


def test_the_worker_side_carries_the_gradient_at_the_state_posted(planar4: Robot) -> None:
    """With ``with_gradient`` each answer carries ``∇_q S`` at the state posted, bit for bit the inline term's: the
    targets' answer, and a route's searches' (its plans come apart)."""
    from previewctl.control.factory import planning_side

    ascent = pc.make_controller(planar_scenario("gradient")).law.ascent  # type: ignore[attr-defined]
    q = np.array(Q0)
    for coherent in (False, True):  # argmax targets; a route's plans
        scenario = planar_scenario("multi", with_gradient=True, coherent=coherent)
        side = planning_side(scenario.controller, scenario.robot, scenario.path, scenario.scene, scenario.index,
                             scenario.potential, np.random.default_rng(0), 0.033, fixed_search)
        answer = side.searches if coherent else side  # a route's searches answer apart from its plans
        first, again = answer(q, 0.0), answer(q, 0.033)
        assert first is not None and again is not None
        for result, t in ((first, 0.0), (again, 0.033)):
            assert result.local is not None and result.local[0] == t
            np.testing.assert_array_equal(result.local[1], ascent.gradient(q, t))


def test_the_loop_applies_the_workers_gradient_while_it_is_valid() -> None:
    """``K_g ∇_q S(q0, t0)`` from the latest result, whatever the configuration now, until ``arms_valid_frames``
    frames after ``t0``; then no local term."""
    from previewctl.control.background import BackgroundGradient, BackgroundPlanning

    planning = BackgroundPlanning(BackgroundOptions(arms_valid_frames=3.0), 0.033)
    gain, gradient = np.array([1.0, 2.0, 3.0, 4.0]), np.array([0.5, -1.0, 2.0, 0.25])
    term = BackgroundGradient(gain, planning)
    q = np.array(Q0)
    np.testing.assert_array_equal(term(q, 0.0), np.zeros(4))  # no result yet
    planning.result = PlanningResult(1.0, 0.01, local=(1.0, gradient))
    for t in (1.0, 1.05, 1.099):
        np.testing.assert_array_equal(term(q + t, t), gain * gradient)
    np.testing.assert_array_equal(term(q, 1.1), np.zeros(4))  # 4 frames late: stale


def test_a_background_run_adds_the_workers_gradient() -> None:
    """``multi`` with ``with_gradient`` in the background: the local term is the inline gradient at the state the worker
    answered, for an arm held still."""
    ascent = pc.make_controller(planar_scenario("gradient")).law.ascent  # type: ignore[attr-defined]
    q = np.array(Q0)
    scenario = planar_scenario("multi", coherent=False, with_gradient=True)
    with pc.make_controller(scenario, search_factory=fixed_search, planning="background") as ctrl:
        k = step_until(ctrl, 0, q, lambda info: not info.fallback)
        t = (k - 1) * DT
        local = ctrl.planning.result.local  # type: ignore[union-attr]
        assert local is not None and t - local[0] <= 3 * ctrl.frame
        np.testing.assert_array_equal(ctrl.law.local(q, t), ascent.gain * ascent.gradient(q, local[0]))  # type: ignore[attr-defined]


LOOP = """
import sys, time
import numpy as np
import previewctl as pc

if __name__ == "__main__":
    scenario = pc.load_scenario(sys.argv[1])
    ctrl = pc.make_controller(scenario, planning="background")  # never closed: Ctrl-C ends the script
    print(ctrl.planning.worker.pid, ctrl.planning.plans.pid, flush=True)  # multi's route: searches, plans
    q, k = np.array(scenario.q0), 0
    while True:
        q = pc.integrate(scenario.robot, q, ctrl.step(q, k * 0.004, 0.004), 0.004)
        k += 1
        time.sleep(0.004)
"""


def test_ctrl_c_in_a_loop_leaves_no_orphan_worker(tmp_path: Path) -> None:
    script = tmp_path / "loop.py"
    script.write_text(LOOP)
    scene = Path(__file__).resolve().parent.parent / "scenarios" / "paper_fitted.toml"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    loop = subprocess.Popen([sys.executable, str(script), str(scene)], stdout=subprocess.PIPE, text=True, env=env,
                            preexec_fn=interruptible)
    try:
        assert loop.stdout is not None
        pids = [int(pid) for pid in loop.stdout.readline().split()]
        time.sleep(2.0)  # the workers start meanwhile
        loop.send_signal(signal.SIGINT)
        loop.wait(timeout=WAIT)
    finally:
        loop.kill()
    assert loop.returncode != 0  # KeyboardInterrupt
    deadline = time.monotonic() + 30.0
    for pid in pids:
        while not gone(pid):  # the workers are not the test's children: poll until they have been reaped
            assert time.monotonic() < deadline, f"worker {pid} outlived its loop"
            time.sleep(0.1)


UNGUARDED = """
import sys, time
import numpy as np
import previewctl as pc

scenario = pc.load_scenario(sys.argv[1])  # no `if __name__ == "__main__":`: the spawned worker runs this again
with pc.make_controller(scenario, planning="background") as ctrl:
    q, k, deadline = np.array(scenario.q0), 0, time.monotonic() + float(sys.argv[2])
    while True:
        ctrl.step(q, k * 0.004, 0.004)
        k += 1
        if ctrl.last_info.worker_error is not None:
            break
        assert time.monotonic() < deadline, "no worker error"
        time.sleep(0.01)
    print(ctrl.last_info.worker_error, flush=True)
"""


def test_a_worker_lost_at_start_says_why_a_script_needs_its_main_guard(tmp_path: Path) -> None:
    script = tmp_path / "unguarded.py"
    script.write_text(UNGUARDED)
    scene = Path(__file__).resolve().parent.parent / "scenarios" / "paper_fitted.toml"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    run = subprocess.run([sys.executable, str(script), str(scene), str(WAIT)], capture_output=True, text=True,
                         env=env, timeout=2 * WAIT)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "exited with code 1 before it was ready" in run.stdout
    assert 'if __name__ == "__main__":' in run.stdout
