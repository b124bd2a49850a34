"""Every code block of README.md and of the documentation (docs/**/*.md) runs.

One test per page, in its own temporary folder; the page's blocks run in order and share that
folder (a file one block writes, the next may read) and one Python namespace.

* ```` ```bash ```` / ```` ```sh ```` blocks: each command (``\\`` continuations joined, ``  #``
  comments dropped) runs: ``splatplan ...`` in-process with small sizes appended (:data:`SMALL`),
  ``python -c CODE`` exec'd, ``mkdir -p D && cd D`` / ``cd D`` change folder. Setup commands that
  a fresh clone has already run by the time the test does (``make``, ``pip``, ``source``, ``git``)
  and commands that never end or are studies (:data:`SKIP`: ``splatplan view``, a server until
  Ctrl-C; ``splatplan eval``, covered by tests/eval) are not run. Anything else fails the test:
  a page may only show commands that this runner can check.
* ```` ```python ```` blocks are exec'd.
* Other languages (``text``, ``yaml``, ``json``, ``console``) are examples of files and outputs: not run.
* A block right after a line ``<!-- skip-test: REASON -->`` is not run (big data, long runs, a GPU);
  the reason is required. Keep these few.

``plan`` and ``mpc`` may exit 1 (no result within the small budget is an accepted outcome of an
example); every other command must exit 0.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README] + sorted((ROOT / "docs").rglob("*.md"))

#: extra flags that keep a line fast (appended to the page's own; argparse lets the last one win)
SMALL = {
    ("mpc",): ["--arm-max-steps", "2", "--base-max-steps", "2", "--device", "cpu"],
    ("plan",): ["--time-limit", "2", "--device", "cpu"],
    ("check",): ["--device", "cpu"],
    ("render",): ["--width", "64", "--height", "64", "--device", "cpu"],
}
SKIP = (("view",), ("eval",))
SETUP = ("make", "pip", "python -m pip", "source", "git", "sudo", "apt-get")
RUN_LANGS = {"bash": "bash", "sh": "bash", "shell": "bash", "python": "python", "py": "python"}
FENCE = re.compile(r"^(?P<indent> *)```(?P<lang>[\w+-]*)[^\n]*\n(?P<body>.*?)^(?P=indent)```", re.S | re.M)
SKIP_MARK = re.compile(r"<!-- skip-test: (?P<reason>[^>]*\S)\s*-->\s*$")


def code_blocks(path: Path) -> list[tuple[str, str, str | None]]:
    """``(language, body, skip reason or None)`` for each fenced block of a page."""
    text = path.read_text()
    out = []
    for m in FENCE.finditer(text):
        before = text[: m.start()].rstrip("\n").rsplit("\n", 1)[-1]
        skip = SKIP_MARK.search(before)
        body = "\n".join(ln[len(m.group("indent")) :] for ln in m.group("body").splitlines())
        out.append((m.group("lang").lower(), body, skip.group("reason") if skip else None))
    return out


def commands(bash: str) -> list[str]:
    joined = re.sub(r"\\\n\s*", " ", bash)
    lines = [re.split(r"\s+#", ln, maxsplit=1)[0].strip() if not ln.lstrip().startswith("#") else "" for ln in joined.splitlines()]
    return [ln for ln in lines if ln]


def _extra(argv: list[str]) -> list[str] | None:
    for key in SKIP:
        if tuple(argv[: len(key)]) == key:
            return None
    for key, extra in SMALL.items():
        if tuple(argv[: len(key)]) == key:
            return extra
    return []


def run_bash(cmds: list[str], cwd: list[Path], monkeypatch, capsys) -> int:
    from splatplan.cli import main

    ran = 0
    for ln in cmds:
        if ln.startswith(SETUP):
            continue
        m = re.fullmatch(r"(?:mkdir -p (\S+) && )?cd (\S+)", ln)
        if m:
            new = cwd[0] / m.group(2)
            new.mkdir(parents=True, exist_ok=True)
            cwd[0] = new
            monkeypatch.chdir(new)
            continue
        if ln.startswith("mkdir -p "):
            for d in shlex.split(ln)[2:]:
                (cwd[0] / d).mkdir(parents=True, exist_ok=True)
            continue
        if ln.startswith("python -c "):
            exec(compile(shlex.split(ln)[2], "<docs>", "exec"), {})
            ran += 1
            continue
        assert ln.startswith("splatplan "), f"the docs test cannot run this line (see tests/test_readme.py): {ln}"
        argv = shlex.split(ln)[1:]
        extra = _extra(argv)
        if extra is None:
            continue
        rc = main(argv + extra)
        ok = (0, 1) if argv[0] in ("plan", "mpc") else (0,)
        assert rc in ok, (ln, rc, capsys.readouterr().err)
        ran += 1
    return ran


@pytest.mark.slow  # the pages write built-in scenes and run plan, check, mpc and render at small sizes
@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_code_blocks_run(page, tmp_path, monkeypatch, capsys):
    blocks = code_blocks(page)
    monkeypatch.chdir(tmp_path)
    cwd = [tmp_path]
    namespace: dict = {"__name__": "__docs__"}
    for lang, body, skip in blocks:
        kind = RUN_LANGS.get(lang)
        if kind is None or skip:
            continue
        if kind == "bash":
            run_bash(commands(body), cwd, monkeypatch, capsys)
        else:
            exec(compile(body, f"<{page.name}>", "exec"), namespace)


def test_skip_markers_are_few_and_give_a_reason():
    """Skipped blocks are the exception: at most a quarter of a page's runnable blocks, each with its reason."""
    total = skipped = 0
    for page in PAGES:
        for lang, _, skip in code_blocks(page):
            if lang in RUN_LANGS:
                total += 1
                skipped += skip is not None
        assert "<!-- skip-test -->" not in page.read_text(), f"{page}: a skip-test marker needs a reason"
    assert skipped <= max(3, total // 4), (skipped, total)


def test_readme_is_a_front_door():
    """The README stays short and starts with the two commands."""
    lines = README.read_text().splitlines()
    assert len(lines) <= 200, len(lines)
    head = "\n".join(lines[:40])
    assert "make demo" in head and "make test" in head


def test_no_history_or_issue_numbers_in_readme_and_docs():
    """History goes to CHANGELOG.md; the README and the docs describe what is."""
    bad = re.compile(r"issue\s*#|issue\s+[0-9]|\(was |, was |\bwas \d", re.I)
    for page in PAGES:
        for i, line in enumerate(page.read_text().splitlines(), 1):
            assert not bad.search(line), f"{page.relative_to(ROOT)}:{i}: {line.strip()}"
