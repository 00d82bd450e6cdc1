"""The sweep: the run matrix, what is missing from the results, and running it on a Dask cluster.

Tasks are plain specs (:class:`~previewctl.bench.runs.RunSpec`, and for the scenes the robot name,
index, seed and :class:`~previewctl.bench.settings.SceneSettings`); each worker builds its own
Pinocchio and Coal objects. A scene is generated once, as a task of its own that its runs depend on,
unless ``scenes.jsonl`` already holds it. The client appends each result to ``results.jsonl`` as it
arrives, so a sweep stopped at any point resumes with the runs that are missing.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

from pydantic import Field, InstanceOf

from previewctl.bench.keep import RUNS_FOLDER, keep_run, run_folder, runs_to_keep
from previewctl.bench.pink import BARRIER_GAINS, pink_module
from previewctl.bench.pink import EXECUTION as PINK_EXECUTION
from previewctl.bench.provenance import stamp
from previewctl.bench.results import append_record, read_records
from previewctl.bench.robots import VALID_ROBOTS, bench_source, profile
from previewctl.bench.runs import (
    INLINE,
    KNOWN,
    LATENCIES,
    SENSINGS,
    RunSpec,
    record_key,
    run,
    run_latency,
    run_sensing,
    settings_hash,
)
from previewctl.bench.scenes import BenchScene, generate
from previewctl.bench.settings import SceneSettings
from previewctl.control import params as control_params
from previewctl.errors import ParameterError, PreviewctlError, UnknownNameError
from previewctl.extras import require
from previewctl.validation import Checked, Count, Integer, Text
from previewctl.viz.replay import REPLAY_NAME

_log = logging.getLogger(__name__)

WORKER_MALLOC = {"MALLOC_MMAP_THRESHOLD_": 1 << 28, "MALLOC_TRIM_THRESHOLD_": 1 << 30}
"""glibc settings of the local cluster's worker processes [bytes]. Dask starts its workers with
``MALLOC_TRIM_THRESHOLD_ = 64 KiB``, so the reachability DP's arrays of a few to tens of MB, allocated and freed
at every step, go back to the system and page-fault on every reuse (measured:
docs/decisions.md#malloc-thresholds-of-the-benchmarks-workers)."""
RESULTS_NAME = "results.jsonl"
SCENES_NAME = "scenes.jsonl"


@dataclass(frozen=True)
class Sweep(Checked):
    """What to run: robots x scenes x controller seeds x controllers x execution modes x latencies x sensings; every
    field is checked when made (a bad count, seed or type raises :class:`~previewctl.errors.ParameterError` naming it).

    Attributes:
        robots: robot names or URDF files (:mod:`previewctl.bench.robots`; a file becomes its absolute path).
        scenes: scenes per robot (indices ``0 .. scenes - 1``).
        controllers: controller names (empty: every name of ``CONTROLLER_NAMES``, read at run time;
            ``none`` under the QP runs as ``qp``, ``qp`` under the pseudo-inverse as ``none``), or pink baselines
            (:data:`~previewctl.bench.pink.BARRIER_GAINS`, only when named; they run under the QP mode only).
        executions: execution modes (empty: every one of ``EXECUTION_MODES``).
        seeds: controller seeds, each once (of the controllers that draw random numbers; the others run once per
            scene, as seed 0).
        scene_seed: the seed the scenes are drawn with.
        settings: what every scene shares (duration, dt, witness).
        latencies: when the plans take effect, each of :data:`~previewctl.bench.runs.LATENCIES` (a controller
            without a replanned window planner runs inline only, :func:`~previewctl.bench.runs.run_latency`).
        sensings: what the controllers know of the moving obstacles, each of
            :data:`~previewctl.bench.runs.SENSINGS` (``none`` and ``oracle`` run with perfect foresight only,
            :func:`~previewctl.bench.runs.run_sensing`).
    """

    robots: tuple[Text, ...] = ("planar4",)
    scenes: Count = 10
    controllers: tuple[Text, ...] = ()
    executions: tuple[Text, ...] = ()
    seeds: tuple[Annotated[Integer, Field(ge=0)], ...] = (0,)
    scene_seed: Annotated[Integer, Field(ge=0)] = 0
    settings: InstanceOf[SceneSettings] = field(default_factory=SceneSettings)
    latencies: tuple[Text, ...] = (INLINE,)
    sensings: tuple[Text, ...] = (KNOWN,)

    def check(self) -> None:
        """Every name, and each robot's profile (each field's type and count is checked by its annotation first);
        a robot's source made canonical (:func:`~previewctl.bench.robots.bench_source`).

        Raises:
            UnknownNameError: an unknown robot, controller, execution mode, latency or sensing (the valid ones
                listed).
            MissingExtraError: a pink baseline named without pink installed.
            RobotLoadError: a missing URDF file or one that does not load as an arm.
            ParameterError: no robot, no seed, no latency, no sensing, or an arm no profile can be derived for.
        """
        if not self.robots:
            raise ParameterError(f"give at least one robot; valid: {', '.join(VALID_ROBOTS)}")
        if not self.seeds:
            raise ParameterError("give at least one controller seed, e.g. seeds=(0,)")
        if not self.latencies:
            raise ParameterError(f"give at least one latency; valid: {', '.join(LATENCIES)}")
        if not self.sensings:
            raise ParameterError(f"give at least one sensing; valid: {', '.join(SENSINGS)}")
        object.__setattr__(self, "robots", tuple(bench_source(robot) for robot in self.robots))
        for robot in self.robots:
            profile(robot)
        for name in self.controllers:
            if name not in control_params.CONTROLLER_NAMES and name not in BARRIER_GAINS:
                raise UnknownNameError("controller", name, (*control_params.CONTROLLER_NAMES, *BARRIER_GAINS))
        if any(name in BARRIER_GAINS for name in self.controllers):
            pink_module()  # before a cluster starts: one line naming the extra
        for name in self.executions:
            if name not in control_params.EXECUTION_MODES:
                raise UnknownNameError("execution mode", name, control_params.EXECUTION_MODES)
        for name in self.latencies:
            if name not in LATENCIES:
                raise UnknownNameError("latency", name, LATENCIES)
        for name in self.sensings:
            if name not in SENSINGS:
                raise UnknownNameError("sensing", name, SENSINGS)

    def runs(self) -> list[RunSpec]:
        """The whole matrix, scene by scene (a scene's runs are neighbours, so workers reuse its scenario).

        ``none`` runs under the pseudo-inverse only, ``qp`` and the pink baselines under the QP only
        (:func:`run_pairs`); a controller that draws no random numbers runs for
        seed 0 only (:func:`~previewctl.control.params.run_seed`), one without a replanned planner inline only
        (:func:`~previewctl.bench.runs.run_latency`), and ``none``, ``oracle`` and the pink baselines with perfect
        foresight only (:func:`~previewctl.bench.runs.run_sensing`)."""
        pairs = run_pairs(self.controllers or control_params.CONTROLLER_NAMES,
                          self.executions or control_params.EXECUTION_MODES)
        specs = []
        for robot in self.robots:
            settings = settings_hash(robot, self.scene_seed, self.settings)
            for scene in range(self.scenes):
                runs = dict.fromkeys((control_params.run_seed(name, seed), name, execution,
                                      run_latency(name, latency), run_sensing(name, sensing))
                                     for sensing in self.sensings for latency in self.latencies
                                     for seed in self.seeds for name, execution in pairs)  # each run once, in order
                specs += [RunSpec(robot, scene, seed, name, execution, settings, self.scene_seed, latency, sensing)
                          for seed, name, execution, latency, sensing in runs]
        return specs


def run_pairs(names: tuple[str, ...], executions: tuple[str, ...]) -> list[tuple[str, str]]:
    """The ``(controller, execution)`` pairs of ``names`` × ``executions``, in order (names outer): previewctl's
    controllers as :func:`~previewctl.control.params.controller_runs` says, a pink baseline under
    :data:`~previewctl.bench.pink.EXECUTION` only (if it is asked for)."""
    pairs: list[tuple[str, str]] = []
    for name in names:
        if name in BARRIER_GAINS:
            pairs += [(name, PINK_EXECUTION)] if PINK_EXECUTION in executions else []
        else:
            pairs += control_params.controller_runs([name], executions)
    return pairs


@dataclass
class SweepOutcome:
    """What a call of :func:`run_sweep` did.

    Attributes:
        planned: runs in the matrix.
        skipped: runs already in the results file.
        done: runs completed now.
        failed: ``(run, error message)`` of the runs that raised.
    """

    planned: int
    skipped: int
    done: int = 0
    failed: list[tuple[RunSpec, str]] = field(default_factory=list)


def missing_runs(sweep: Sweep, results: Path) -> tuple[list[RunSpec], int]:
    """The runs of ``sweep`` not yet in ``results``, and how many there are in all."""
    done = {record_key(r) for r in read_records(results)}
    planned = sweep.runs()
    return [spec for spec in planned if spec.key not in done], len(planned)


def run_sweep(sweep: Sweep, out: Path, client: Any, on_result: Callable[[dict[str, Any]], None] | None = None,
              on_start: Callable[[int], None] | None = None) -> SweepOutcome:
    """Run the missing runs of ``sweep`` on the Dask ``client``; append each result to ``out/results.jsonl``,
    stamped with the time it arrived and the client's commit (:func:`~previewctl.bench.provenance.stamp`).

    Args:
        sweep: the matrix.
        out: the output folder (created).
        client: a ``distributed.Client``.
        on_result: called with each result line as it is written (e.g. to advance a progress bar).
        on_start: called with the number of runs to do, before the first is submitted.
    """
    from distributed import as_completed

    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PreviewctlError(f"cannot create the output folder {str(out)!r}: {exc}") from exc
    results, scenes_file = out / RESULTS_NAME, out / SCENES_NAME
    todo, planned = missing_runs(sweep, results)
    outcome = SweepOutcome(planned=planned, skipped=planned - len(todo))
    _log.info("sweep: %d runs planned, %d already in %s", planned, outcome.skipped, results)
    if on_start is not None:
        on_start(len(todo))
    known = {(r["robot"], r["index"], r["settings"]): r for r in read_records(scenes_file)}
    scene_tasks: dict[tuple[str, int, str], Any] = {}
    futures = {}
    for spec in todo:
        key = (spec.robot, spec.scene, spec.settings)
        if key not in scene_tasks:
            if key in known:
                scene_tasks[key] = client.scatter(BenchScene.from_record(known[key]))
            else:
                scene_tasks[key] = client.submit(generate, spec.robot, spec.scene, spec.scene_seed, sweep.settings,
                                                 pure=False)
        futures[client.submit(run, spec, scene_tasks[key], pure=False)] = (spec, key)
    fetched: dict[tuple[str, int, str], BenchScene] = {}
    for future in as_completed(futures):
        spec, key = futures[future]
        if future.status != "finished":
            outcome.failed.append((spec, f"{type(future.exception()).__name__}: {future.exception()}"))
            _log.warning("run %s failed: %s", spec, outcome.failed[-1][1])
            continue
        record = future.result()
        if key not in fetched:
            fetched[key] = scene_tasks[key].result()
            if key not in known:
                append_record(scenes_file, {**dataclasses.asdict(fetched[key]), "settings": spec.settings})
        append_record(results, {**record, "scene_rejected": fetched[key].rejected,
                                "motions": sweep.settings.motions, "history": sweep.settings.history, **stamp()})
        outcome.done += 1
        if on_result is not None:
            on_result(record)
    return outcome


def keep_runs(out: Path, client: Any, failures: int, on_done: Callable[[], None] | None = None,
              on_start: Callable[[int], None] | None = None) -> list[str]:
    """Write the kept runs (:mod:`previewctl.bench.keep`) of ``out/results.jsonl`` that are not yet in
    ``out/runs/``, on the Dask ``client``; the folders written (the ones that raised are left out)."""
    scenes = {(r["robot"], r["index"], r["settings"]): r for r in read_records(out / SCENES_NAME)}
    fields = [f.name for f in dataclasses.fields(RunSpec)]
    todo = [r for r in runs_to_keep(read_records(out / RESULTS_NAME), failures)
            if not (out / RUNS_FOLDER / run_folder(r) / REPLAY_NAME).is_file()]
    if on_start is not None:
        on_start(len(todo))
    futures = []
    for r in todo:
        scene = BenchScene.from_record(scenes[(r["robot"], r["scene"], r["settings"])])
        spec = RunSpec(**{name: r[name] for name in fields if name in r})  # older lines: the fields' defaults
        futures.append(client.submit(keep_run, spec, scene, str(out / RUNS_FOLDER / run_folder(r)), pure=False))
    from distributed import as_completed

    written = []
    for future in as_completed(futures):
        if future.status == "finished":
            written.append(future.result())
        if on_done is not None:
            on_done()
    return written


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None) -> Iterator[Any]:
    """A Dask client: of the cluster at ``scheduler``, or of a ``LocalCluster`` of ``workers`` processes
    (default: one per core), one thread each, without a dashboard, started with :data:`WORKER_MALLOC`.

    Raises:
        MissingExtraError: Dask is not installed.
    """
    distributed = require("distributed", "bench", "a benchmark sweep")
    dask = require("dask", "bench", "a benchmark sweep")
    Client, LocalCluster = distributed.Client, distributed.LocalCluster
    if scheduler is not None:
        with Client(scheduler) as client:
            yield client
        return
    count = workers if workers is not None else (os.cpu_count() or 1)
    if count < 1:
        raise ParameterError(f"workers must be >= 1, got {count!r}")
    environ = {**dask.config.get("distributed.nanny.pre-spawn-environ", {}), **WORKER_MALLOC}
    with dask.config.set({"distributed.nanny.pre-spawn-environ": environ}), \
            LocalCluster(n_workers=count, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        yield client
