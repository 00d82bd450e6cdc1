"""Tests of :mod:`previewctl.files`: result files are written completely or not at all."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import pytest

from previewctl.errors import OutputError
from previewctl.files import (
    append_line,
    atomic_folder,
    atomic_write,
    atomic_write_bytes,
    check_output_file,
    check_output_folder,
    remove_stale,
    save_figure,
)


def test_failed_write_keeps_the_old_file_and_leaves_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "summary.json"
    target.write_bytes(b"old")

    def fail_halfway(handle: object) -> None:
        handle.write(b"partial")  # type: ignore[attr-defined]
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError, match="disk full"):
        atomic_write(target, fail_halfway)
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]


def test_save_figure_follows_the_suffix_and_fails_cleanly(tmp_path: Path) -> None:
    fig, ax = plt.subplots()
    try:
        ax.plot([0, 1], [0, 1])
        png = save_figure(fig, tmp_path / "plot.png", dpi=50)
        svg = save_figure(fig, tmp_path / "plot.svg")
        plain = save_figure(fig, tmp_path / "plot", dpi=50)
        with pytest.raises(ValueError, match="xyz"):
            save_figure(fig, tmp_path / "plot.xyz")
    finally:
        plt.close(fig)
    assert png.read_bytes().startswith(b"\x89PNG") and plain.read_bytes().startswith(b"\x89PNG")
    assert b"<svg" in svg.read_bytes()[:500]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plot", "plot.png", "plot.svg"]


# ------------------------------------------------------------------------------ one place each

PACKAGE = Path(__file__).resolve().parent.parent / "previewctl"
WRITERS = {"savefig", "savez", "savez_compressed", "save", "write_text", "write_bytes", "dump", "tofile", "fdopen"}
"""Calls that write a file when given a path (``np.save``, ``Image.save``, ``json.dump``, ...)."""


def package_modules() -> list[tuple[str, ast.Module]]:
    return [(path.relative_to(PACKAGE.parent).as_posix(), ast.parse(path.read_text(), str(path)))
            for path in sorted(PACKAGE.rglob("*.py"))]


def called_name(call: ast.Call) -> str:
    func = call.func
    return func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else ""


def writes_a_file(call: ast.Call) -> bool:
    name = called_name(call)
    if name == "open":  # builtin open or Path.open: only a write mode counts
        modes = [a.value for a in call.args if isinstance(a, ast.Constant) and isinstance(a.value, str)]
        modes += [k.value.value for k in call.keywords
                  if k.arg == "mode" and isinstance(k.value, ast.Constant) and isinstance(k.value.value, str)]
        return any(set(mode) & set("wax+") for mode in modes)
    return name in WRITERS


def test_only_files_py_writes_result_files() -> None:
    """Outside previewctl/files.py a write happens only inside a callable handed to ``atomic_write``
    (which gives it a temporary file), so every result file is written completely or not at all."""
    offenders = []
    for name, tree in package_modules():
        if name == "previewctl/files.py":
            continue
        parents = {child: node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}
        for call in (n for n in ast.walk(tree) if isinstance(n, ast.Call) and writes_a_file(n)):
            node: ast.AST = call
            while node in parents and not (
                isinstance(node, ast.Lambda)
                and isinstance(parents[node], ast.Call)
                and called_name(parents[node]).startswith("atomic_write")
            ):
                node = parents[node]
            if not isinstance(node, ast.Lambda):
                offenders.append(f"{name}:{call.lineno} {called_name(call)}")
    assert not offenders, "write these through previewctl.files.atomic_write: " + ", ".join(offenders)


def test_only_viz_imports_matplotlib_and_pillow() -> None:
    """Plotting stays in previewctl/viz/ (files.py saves a Figure it is handed, without importing matplotlib)."""
    offenders = []
    for name, tree in package_modules():
        if name.startswith("previewctl/viz/"):
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                modules = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                modules = [node.module or ""]
            else:
                continue
            offenders += [f"{name}:{node.lineno} {m}" for m in modules if m.split(".")[0] in ("matplotlib", "PIL")]
    assert not offenders, "only previewctl/viz/ draws: " + ", ".join(offenders)


# ------------------------------------------------------------------------------ whole folders

ROOT = Path(__file__).resolve().parent.parent


def dead_pid() -> int:
    """The id of a process that has ended."""
    child = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True,
                           check=True)
    return int(child.stdout)


def old_folder(tmp_path: Path) -> Path:
    out = tmp_path / "run"
    out.mkdir()
    (out / "summary.json").write_text("old")
    (out / "strobe.png").write_text("old figure")
    return out


def test_folder_is_replaced_whole(tmp_path: Path) -> None:
    out = old_folder(tmp_path)
    with atomic_folder(out) as folder:
        (folder / "summary.json").write_text("new")
        assert (out / "summary.json").read_text() == "old"  # the old folder stays until the end
    assert sorted(p.name for p in out.iterdir()) == ["summary.json"]  # no old figure mixed in
    assert (out / "summary.json").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_failed_folder_keeps_the_old_one_and_leaves_no_temporary(tmp_path: Path) -> None:
    out = old_folder(tmp_path)
    with pytest.raises(RuntimeError, match="disk full"), atomic_folder(out) as folder:
        (folder / "summary.json").write_text("new")
        raise RuntimeError("disk full")
    assert sorted(p.name for p in out.iterdir()) == ["strobe.png", "summary.json"]
    assert (out / "summary.json").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_temporaries_of_dead_processes_are_removed_and_living_ones_kept(tmp_path: Path) -> None:
    out, dead, alive = tmp_path / "map.png", dead_pid(), os.getpid()
    stale = [tmp_path / f".map.png.{dead}.abc123.tmp", tmp_path / f".strobe.png.{dead}.x.tmp"]
    (tmp_path / f".map.png.{dead}.folder1.tmp").mkdir()
    living = tmp_path / f".map.png.{alive}.busy.tmp"
    for path in (*stale, living):
        path.write_text("partial")
    atomic_write_bytes(out, b"png")
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == [living.name, stale[1].name, "map.png"]  # only map.png's dead temporaries go


def test_an_old_folder_set_aside_by_a_killed_swap_is_put_back(tmp_path: Path) -> None:
    aside = tmp_path / f".run.{dead_pid()}.q1w2e3.old"
    aside.mkdir()
    (aside / "summary.json").write_text("old")
    remove_stale(tmp_path / "run")
    assert (tmp_path / "run" / "summary.json").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_run_killed_while_writing_leaves_the_old_folder_whole(tmp_path: Path) -> None:
    """SIGKILL a real ``previewctl run`` once its new log is written and its figures are not: the old folder
    is untouched, and the next run removes the killed run's temporary folder."""
    scenario = ROOT / "scenarios" / "planar_free.toml"  # gif = true: seconds of figure writing to kill into
    out = old_folder(tmp_path)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    argv = [sys.executable, "-m", "previewctl", "run", str(scenario), "--out", str(out)]
    child = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    try:
        while not list(tmp_path.glob(f".run.{child.pid}.*.tmp/run.npz")):
            assert child.poll() is None and time.monotonic() < deadline, "the run ended before it was killed"
            time.sleep(0.005)
    finally:
        child.kill()
        child.wait()
    assert sorted(p.name for p in out.iterdir()) == ["strobe.png", "summary.json"]
    assert (out / "summary.json").read_text() == "old"
    (killed,) = [p for p in tmp_path.iterdir() if p.name != "run"]
    assert killed.name.startswith(f".run.{child.pid}.") and (killed / "run.npz").is_file()
    done = subprocess.run([*argv, "--no-gif", "--controller", "none"], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]
    assert json.loads((out / "summary.json").read_text())["controller"] == "none"
    assert not (out / "run.gif").exists() and (out / "run.npz").is_file()


def test_append_line_after_a_torn_last_line_starts_a_new_line(tmp_path: Path) -> None:
    """A crash mid-append leaves a torn line; the next record must not be glued onto it."""
    log = tmp_path / "results.jsonl"
    append_line(log, '{"a": 1}')
    with log.open("ab") as handle:  # the torn tail of a crashed writer
        handle.write(b'{"b": ')
    append_line(log, '{"c": 3}\n')
    assert log.read_bytes() == b'{"a": 1}\n{"b": \n{"c": 3}\n'


def test_a_folder_where_nothing_can_be_made_is_refused_with_the_os_reason(tmp_path: Path) -> None:
    """/proc passes the permission check (for root) but takes no new entry: the check tries, and leaves nothing."""
    with pytest.raises(OutputError, match=r"^output folder '/proc/previewctl-out': cannot write in folder '/proc': "):
        check_output_folder("/proc/previewctl-out")
    with pytest.raises(OutputError, match=r"^output file '/proc/m\.png': cannot write in folder '/proc': "):
        check_output_file("/proc/m.png")
    with pytest.raises(OutputError, match="cannot write in folder '/proc'"), atomic_folder(Path("/proc/run")):
        raise AssertionError("never entered")
    assert check_output_folder(tmp_path / "run") == tmp_path / "run"
    assert list(tmp_path.iterdir()) == [], "the check leaves no trace"
