"""A worker process beside the control loop: started once, handed the latest state, read without waiting.

The exchange is one duplex pipe with at most one message in flight each way. The loop keeps its latest state in a
slot of its own (a newer state replaces an unsent one) and sends it only when the worker is idle; the worker answers
each state with exactly one message (a result, ``None`` for nothing new, or the error its computation raised); its
start counts as a state in flight, answered once its parts are built. So the pipe never holds more than one message
each way, neither end ever backs up, the worker always starts from the freshest state, and the loop only polls (a
``poll()`` and at most one small ``send`` per cycle, never a blocking read of an empty pipe). A queue would back up
behind a slow worker; shared memory would need a lock the worker may die holding. A state's ``q`` travels as a list
of floats (the same bits; pickled in 2.4 µs against 8-10 µs for an array, warm), and
:meth:`PlanningWorker.rehearse` runs the code of an exchange without its messages, so that a real-time loop can bring
it back into the caches before its deadline.

The worker is a *spawned* process (Pinocchio and Coal keep the GIL, so a thread would stall the loop; a fork of a
process with threads is unsafe): it rebuilds its parts from the picklable ``build`` it is given, lowers its OS
priority by ``niceness``, runs only on the ``cores`` it is given (the loop's own core left out: a worker woken by
the loop's message would otherwise be placed on the loop's core and delay it) and ignores SIGINT (Ctrl-C stops the
loop, whose :meth:`PlanningWorker.close` ends the worker). A worker that exits, raises, or does not answer within
``timeout`` is reported as a :class:`~previewctl.errors.PlanningWorkerError`; the loop goes on without it.
:meth:`PlanningWorker.close` asks it to stop, then terminates and finally kills it; a ``weakref.finalize`` does the
same for a worker that was never closed.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import pickle
import select
import signal
import time
import weakref
from collections.abc import Callable, Iterator
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from multiprocessing.reduction import ForkingPickler
from typing import Any

import numpy as np

from previewctl.errors import PlanningWorkerError
from previewctl.types import Array

SINGLE_THREAD = {name: "1" for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
                                        "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")}
"""The worker's environment beside the loop's: one BLAS/OpenMP thread. Its numbers are small matrices, and a pool of
helper threads (one per core by default, spinning a while after each parallel call) would take cores from the loop."""

GRACE = 1.0
"""How long [s] :meth:`PlanningWorker.close` waits for the worker to stop by itself, then after terminating it."""

Compute = Callable[[Any, Array, float], Any]
"""``compute(side, q, t)``: the worker's answer to the state ``(q, t)`` [rad, s], from what ``build()`` made."""


class PlanningWorker:
    """A process that answers the latest state posted (module docstring).

    Args:
        build: a picklable callable, run once in the worker, that makes its parts (``side``).
        compute: a picklable ``compute(side, q, t)`` run for each state the worker receives.
        timeout: how long [s] of wall time a state may stay unanswered before the worker counts as hung.
        niceness: how much the worker lowers its OS priority (``os.nice``).
        cores: the CPUs the worker may run on (``os.sched_setaffinity``); ``None``: those of this process.

    Attributes:
        error: why the worker gives no result (``None`` while it answers).
        pid: the worker's process id.
        answered: how many answers the worker has sent: its ready message, then one per state (an error counts).
    """

    def __init__(self, build: Callable[[], Any], compute: Compute, *, timeout: float, niceness: int,
                 cores: frozenset[int] | None = None) -> None:
        context = multiprocessing.get_context("spawn")
        self._conn, child = context.Pipe(duplex=True)
        self._process = context.Process(target=_serve, args=(child, build, compute, niceness), daemon=True,
                                        name="previewctl-planning")
        with _environment(SINGLE_THREAD):  # a spawned child reads its thread counts before it imports numpy
            self._process.start()
        child.close()
        self.pid = int(self._process.pid or 0)
        if cores:
            with contextlib.suppress(OSError):  # none of them allowed (a container's cpuset): the process's own
                os.sched_setaffinity(self.pid, cores)
        self.timeout = timeout
        self.error: PlanningWorkerError | None = None
        self.answered = 0
        self._slot: tuple[list[float], float, Any] | None = None
        self._last_sent: tuple[list[float], float, Any] | None = None  # what rehearse() pickles again
        self._last_answer: bytes | None = None  # the last answer as it came, which rehearse() unpickles again
        # perf_counter [s] of the state in flight, None when the worker is idle; its start counts as one (it answers
        # None once its parts are built), so its first state is the freshest one then, not the first one posted
        self._sent_at: float | None = time.perf_counter()
        self._readable = _poller(self._conn)
        self._finalizer = weakref.finalize(self, _stop, self._process, self._conn)

    def post(self, q: Array, t: float, news: Any = None) -> None:
        """Put the state ``(q, t)`` in the slot (replacing an unsent one); it goes out when the worker is idle.
        ``news`` (not ``None``): what the worker's side takes first, by ``side.sync(news)``."""
        self._slot = (q.tolist(), t, news)

    @property
    def busy(self) -> bool:
        """Whether a state sent is still unanswered (the worker's start counts as one)."""
        return self._sent_at is not None

    @property
    def waiting(self) -> bool:
        """Whether a posted state is still in the slot (the worker was busy)."""
        return self._slot is not None

    def exchange(self) -> list[Any]:
        """The answers received since the last call (at most one), and the slot sent if the worker is idle.

        Never waits. Sets :attr:`error` when the worker has exited, raised, or not answered within the timeout.
        """
        answers: list[Any] = []
        if not self._finalizer.alive:
            self.error = self.error or PlanningWorkerError(f"the planning worker (pid {self.pid}) was closed")
            return answers
        try:
            if self._sent_at is not None and self._has_message():
                self._last_answer = self._conn.recv_bytes()
                answer = pickle.loads(self._last_answer)
                self._sent_at = None
                self.answered += 1
                if isinstance(answer, PlanningWorkerError):
                    self.error = answer
                else:
                    self.error = None
                    answers.append(answer)
            if self._sent_at is None and self._slot is not None:
                self._conn.send(self._slot)
                self._last_sent, self._slot, self._sent_at = self._slot, None, time.perf_counter()
        except (EOFError, OSError):
            self.error = PlanningWorkerError(f"the planning worker (pid {self.pid}) exited with code "
                                             f"{self._exit_code()}{self._start_hint()}: no more plans")
            self.close()
            return answers
        if self._sent_at is not None and time.perf_counter() - self._sent_at > self.timeout:
            self.error = PlanningWorkerError(f"the planning worker (pid {self.pid}) has not answered for more than "
                                             f"{self.timeout:g} s (the timeout)")
        return answers

    def rehearse(self) -> None:
        """Run the code of an exchange without sending or taking anything: pickle the last state sent, unpickle the
        last answer (and drop it), poll the pipe. Changes nothing; nothing once the worker is closed."""
        if not self._finalizer.alive:
            return
        if self._last_sent is not None:
            ForkingPickler.dumps(self._last_sent)
        if self._last_answer is not None:
            pickle.loads(self._last_answer)
        with contextlib.suppress(OSError):
            self._has_message()

    def _has_message(self) -> bool:
        """Whether the worker's pipe holds a message or its end (a closed pipe): one ``poll(0)`` on a poller made
        once, where ``Connection.poll()`` makes a selector per call (3 µs warm, 20 µs at the loop's median)."""
        return bool(self._readable.poll(0)) if self._readable is not None else self._conn.poll()

    def _start_hint(self) -> str:
        """Why a worker that exits before it is ready most often does: its spawn imports the main script again."""
        if self.answered:
            return ""
        return (" before it was ready (its own error is on stderr). The worker is a spawned process that imports "
                "the main script again: a script that makes a background controller must run it under "
                "`if __name__ == \"__main__\":`")

    def _exit_code(self) -> int | None:
        self._process.join(GRACE)
        return self._process.exitcode

    def close(self) -> None:
        """Stop the worker (a request, then SIGTERM, then SIGKILL, :data:`GRACE` apart) and reap it; idempotent."""
        self._finalizer()


def _poller(conn: Connection) -> select.poll | None:
    """A poller of ``conn``'s input, or ``None`` where the OS has no ``poll`` (Windows: ``Connection.poll`` then)."""
    if not hasattr(select, "poll"):
        return None
    poller = select.poll()
    poller.register(conn.fileno(), select.POLLIN)
    return poller


def _stop(process: BaseProcess, conn: Connection) -> None:
    """Ask ``process`` to stop, terminate it, kill it, each after :data:`GRACE`; join it and close the pipe."""
    with contextlib.suppress(OSError, ValueError):  # the worker is gone already, or the pipe closed
        conn.send(None)
    process.join(GRACE)
    if process.is_alive():
        process.terminate()
        process.join(GRACE)
    if process.is_alive():
        process.kill()
        process.join()
    conn.close()


@contextlib.contextmanager
def _environment(values: dict[str, str]) -> Iterator[None]:
    """``os.environ`` with ``values`` set while a child process is spawned (it copies the environment), then as it
    was (this process's own thread pools were made when it imported numpy: unchanged)."""
    saved = {name: os.environ.get(name) for name in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _serve(conn: Connection, build: Callable[[], Any], compute: Compute, niceness: int) -> None:
    """The worker's main: build the parts, then answer each state until ``None`` comes or the pipe closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.nice(niceness)
    side = build()
    conn.send(None)  # ready
    while True:
        try:
            message = conn.recv()
        except EOFError:
            return
        if message is None:
            return
        values, t, news = message
        q = np.array(values, dtype=float)
        try:
            if news is not None:
                side.sync(news)
            answer = compute(side, q, t)
        except Exception as exc:  # reported to the loop, which falls back; the worker serves on
            answer = PlanningWorkerError(f"planning failed at t = {t:g} s: {type(exc).__name__}: {exc}")
        conn.send(answer)
