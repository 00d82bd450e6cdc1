"""``benchmarks/bench_preview.py`` runs as a user runs it: its ``--set`` values read as the scenario file's
``[controller]`` table, bad input in one line, and a controller without a random stream counted once per seed."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from helpers import tiny_planar_toml

ROOT = Path(__file__).resolve().parent.parent


def _bench_preview(tmp_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    scene = tmp_path / "tiny.toml"
    scene.write_text(tiny_planar_toml("tiny", "[timing]\nduration = 0.5\n"))
    return subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "bench_preview.py"), "--workers", "1", *args, str(scene)],
        capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(ROOT)}, cwd=tmp_path, timeout=300,
    )


def test_bench_preview_takes_toml_values_and_counts_an_unseeded_controller_for_every_seed(tmp_path: Path) -> None:
    done = _bench_preview(tmp_path, "--seed", "0-1", "--controller", "none,multi", "--set", "gain=2.0",
                          "--set", "weights=[0.2, 0.3, 0.5]", "--set", "execution=pseudoinverse")
    assert done.returncode == 0, done.stderr
    rows = {line.split()[0]: line.split() for line in done.stdout.splitlines() if line.startswith(("none", "multi"))}
    assert rows["none"][1:4] == ["2", "/", "2"] and rows["multi"][1:4] == ["2", "/", "2"]


def test_bench_preview_bad_settings_are_one_line(tmp_path: Path) -> None:
    for setting, message in (("gain=x", "gain must be a list of numbers, got 'x'"),
                             ("gian=2", "unknown controller parameter 'gian'; valid: gain, ")):
        done = _bench_preview(tmp_path, "--set", setting)
        assert done.returncode == 1 and done.stdout == ""
        assert done.stderr.count("\n") == 1 and message in done.stderr, done.stderr


def test_bench_plan_quick_replays_the_plans_it_recorded() -> None:
    """``bench_plan.py --quick``: the Panda plans of one second of ``horizon`` replayed the same, one row."""
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_plan.py"), "--quick"], capture_output=True,
                          text=True, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=300)
    assert done.returncode == 0, done.stderr
    assert "plans replayed, 0 differ from the recorded ones" in done.stdout
    row = next(line.split() for line in done.stdout.splitlines() if line.startswith("panda"))
    plans, p50, p95, top, period = int(row[1]), *map(float, row[2:6])
    assert plans >= 2 and 0 < p50 <= p95 <= top and period == 0.5
