"""The README's Python example runs as written, and the README names the commands CI runs."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"


def test_readme_python_examples_run(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every Python block of the README, run in order in one namespace, from a scratch folder."""
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert len(blocks) >= 2, "the README lost its Python examples"
    monkeypatch.chdir(tmp_path)
    (tmp_path / "scenarios").symlink_to(README.parent / "scenarios")
    namespace: dict[str, object] = {}
    for block in blocks:
        exec(compile(block, "README.md", "exec"), namespace)
    out = capsys.readouterr().out
    assert "[1 2 1]" in out  # planar4's avoidance ranks, as the paper states
    assert "False" in out  # the free-space run does not collide
    assert (tmp_path / "out" / "example" / "summary.json").is_file()


def test_ci_runs_the_readme_test_command() -> None:
    ci = (README.parent / ".ci" / "run").read_text()
    command = 'python3 -m venv .venv && .venv/bin/pip install -q ".[all,test]" && .venv/bin/python -m pytest'
    assert command in README.read_text() and command in ci
    assert "previewctl paper" in README.read_text()
