"""The README's Quick start runs: its bash block (every `splatplan` line in-process, `python -c`
lines exec'd) and its Python snippet, in a temp folder, with small sizes where a line is slow.

Skipped lines: `source` (the venv is already active), `splatplan view` (a server that runs until
Ctrl-C) and `splatplan eval` (a study; `tests/eval` covers them). Small sizes: `mpc` with 2 MPC
steps, renders of 64 x 64, `plan` with a 2 s budget (exit 1, "no path in the time limit", is
an accepted outcome of the example, as its comment says).
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"

#: extra flags that keep a line fast (appended to the README's own)
SMALL = {
    ("mpc",): ["--arm-max-steps", "2", "--device", "cpu"],
    ("plan",): ["--time-limit", "2", "--device", "cpu"],
    ("check",): ["--device", "cpu"],
    ("render",): ["--width", "64", "--height", "64", "--device", "cpu"],
}
SKIP = (("view",), ("eval",))


def quick_start_blocks() -> tuple[list[str], str]:
    text = README.read_text()
    qs = text[text.index("## Quick start") : text.index("\n## ", text.index("## Quick start") + 5)]
    bash = re.search(r"```bash\n(.*?)```", qs, re.S).group(1)
    python = re.search(r"```python\n(.*?)```", qs, re.S).group(1)
    lines = [ln.split("  #")[0].strip() for ln in bash.splitlines()]
    return [ln for ln in lines if ln], python


def _extra(argv: list[str]) -> list[str] | None:
    for key in SKIP:
        if tuple(argv[: len(key)]) == key:
            return None
    for key, extra in SMALL.items():
        if tuple(argv[: len(key)]) == key:
            return extra
    return []


@pytest.mark.slow  # ~1.5 min on 2 busy cores: the Quick start writes a 200k-splat scene and runs plan, check, mpc, render
def test_readme_quick_start_runs(tmp_path, monkeypatch, capsys):
    from splatplan.cli import main

    lines, python = quick_start_blocks()
    assert any(ln.startswith("splatplan plan") for ln in lines) and "centers" in python
    monkeypatch.chdir(tmp_path)
    ran = 0
    for ln in lines:
        if ln.startswith("source "):
            continue
        if ln.startswith("mkdir -p try && cd try"):
            (tmp_path / "try").mkdir()
            monkeypatch.chdir(tmp_path / "try")
            continue
        if ln.startswith("python -c "):
            exec(compile(shlex.split(ln)[2], "<readme>", "exec"), {})
            continue
        assert ln.startswith("splatplan "), ln
        argv = shlex.split(ln)[1:]
        extra = _extra(argv)
        if extra is None:
            continue
        rc = main(argv + extra)
        ok = (0, 1) if argv[0] in ("plan", "mpc") else (0,)
        assert rc in ok, (ln, rc, capsys.readouterr().err)
        ran += 1
    assert ran >= 8
    exec(compile(python, "<readme python>", "exec"), {})  # from the try/ folder, as the README says
