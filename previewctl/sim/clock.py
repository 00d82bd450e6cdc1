"""The simulation's clock: simulated time (the loop waits for the controller) or real time (the controller must keep
up with the wall clock).

A clock yields the loop's cycles as :class:`Tick`\\ s, the deadlines ``k period`` for ``k = 0 .. steps``:

* :func:`simulated_ticks`: every deadline, at its own time ``t_k = k dt``, whatever the cycles cost;
* :func:`wall_ticks`: the simulated time is the wall time since the first tick (``time.perf_counter``, monotonic),
  so the arm integrates ``q̇`` over the real period elapsed. The clock sleeps to each deadline, absolute from the
  start (no drift), sleeping to just before it and spinning the rest (``time.sleep`` overshoots by 50-100 µs). A
  cycle that overruns its period skips the deadlines it passed, without a burst to catch up: the next tick is the
  first deadline still ahead, and its ``elapsed`` covers the whole time the command was applied.

  Given a ``rehearse`` (:meth:`~previewctl.control.controller.Controller.rehearse`), the clock calls it over the last
  part of each period (:data:`REHEARSAL_SHARE`), as long as another call fits before the deadline, instead of
  sleeping: the cycle then starts with the step's code and data in the core's caches. On a shared host the wait
  evicts them, and a paced step cost 2-2.5x an unpaced one in this project's measurements (the Speed page, "Caches
  kept warm"). It keeps the loop's core busy for that part of every period.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from typing import NamedTuple

SPIN = 2e-4
"""The last stretch [s] before a deadline that :func:`wall_ticks` spins instead of sleeping."""
REHEARSAL_SHARE = 0.5
"""The last part of each period over which :func:`wall_ticks` rehearses the step instead of sleeping."""


class Tick(NamedTuple):
    """One cycle of the loop.

    Attributes:
        k: its deadline's index (``0 .. steps``; a real-time clock skips the deadlines an overrun passed).
        t: its time [s] (the simulated time the arm is at).
        elapsed: time [s] since the previous tick: how long the previous command was applied (``period`` at the
            first tick, where nothing was applied).
        late: how long after its deadline the tick woke [s] (0 in simulated time): the cycle has ``period − late``
            left before the next deadline.
    """

    k: int
    t: float
    elapsed: float
    late: float = 0.0


def simulated_ticks(dt: float, steps: int) -> Iterator[Tick]:
    """Every deadline at its own time ``k dt`` [s], ``k = 0 .. steps``."""
    for k in range(steps + 1):
        yield Tick(k, k * dt, dt)


def wall_ticks(period: float, steps: int, rehearse: Callable[[], None] | None = None) -> Iterator[Tick]:
    """The deadlines ``k period`` [s] of the wall clock since the first tick, ``k = 0 .. steps``, each tick at the
    wall time it woke (module docstring); the last one is deadline ``steps``, late if its cycle overran. With
    ``rehearse``, the wait before each deadline calls it (:func:`wait_until`) over the last :data:`REHEARSAL_SHARE` of
    the period."""
    lead, expected = REHEARSAL_SHARE * period, 0.0
    start = time.perf_counter()
    k, last = 0, 0.0
    yield Tick(0, 0.0, period)
    while k < steps:
        k = min(steps, max(k + 1, math.floor((time.perf_counter() - start) / period) + 1))
        expected = wait_until(start + k * period, rehearse, lead, expected)
        t = time.perf_counter() - start
        yield Tick(k, t, t - last, t - k * period)
        last = t


def wait_until(deadline: float, rehearse: Callable[[], None] | None = None, lead: float = 0.0,
               expected: float = 0.0) -> float:
    """Return at ``deadline`` (a ``time.perf_counter`` reading [s]) or just after it: sleep, then spin.

    With ``rehearse``: sleep to ``lead`` [s] before the deadline, then call it again and again while one more call fits
    before the deadline (one as long as the longest so far, or ``expected`` [s] before the first, plus :data:`SPIN`),
    then spin (module docstring). Returns the longest call [s], or ``expected / 2`` if none fitted (so that a long
    one once does not stop the rehearsals for good); 0 without ``rehearse``.
    """
    if rehearse is None:
        lead = SPIN
    ahead = deadline - time.perf_counter()
    if ahead > lead:
        time.sleep(ahead - lead)
    longest = 0.0
    if rehearse is not None:
        while (now := time.perf_counter()) + max(longest, expected) + SPIN < deadline:
            rehearse()
            longest = max(longest, time.perf_counter() - now)
        longest = longest or expected / 2
    while time.perf_counter() < deadline:
        pass
    return longest
