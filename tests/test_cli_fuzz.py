"""Fuzz the whole CLI (issue #21): every command and flag, enumerated from the argparse parser.

Each flag that takes a value gets -1, 0, nan, inf and 1e30; each flag or positional that names a
file or folder also gets a missing file, a directory and an unwritable place (/proc). A case
passes when it either

- exits 2 with exactly one ``splatplan: error:`` line, or
- exits 0 or 1 with a sane result (no NaN in the JSON it wrote, no RuntimeWarning), or
- is still running at the time budget and stops cleanly when interrupted (exit 130),

and never prints a traceback, leaves a temporary file or touches the input files.

Every case is parsed (milliseconds: most hostile values stop there). The cases the parser accepts
run in-process with cheap base arguments (tiny scenes, --quick, few steps) and a time budget
(SIGALRM -> KeyboardInterrupt, as Ctrl-C); ``make test`` runs a seeded sample of them,
``SPLATPLAN_FUZZ_FULL=1`` runs all (about an hour on 2 cores). New commands and flags are
covered automatically; a new command only needs a cheap base in ``BASE`` to be run, not just parsed.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import json
import math
import os
import random
import re
import signal
import stat
import threading
import warnings
import time
from pathlib import Path

import numpy as np
import pytest

from splatplan.cli import build_parser, main

DATA = Path(__file__).parent / "data"
BANANA = str(DATA / "equinor_banana_splat.ply")
FULL = os.environ.get("SPLATPLAN_FUZZ_FULL", "") not in ("", "0")
#: accepted cases run per test in the sampled mode (seeded)
N_SAMPLE = int(os.environ.get("SPLATPLAN_FUZZ_SAMPLE", "10"))
#: seconds a run may take before it is interrupted (then it must end within GRACE_S more)
BUDGET_S = float(os.environ.get("SPLATPLAN_FUZZ_BUDGET_S", "2.0"))
GRACE_S = 20.0

NUMBERS = ("-1", "0", "nan", "inf", "1e30")
#: issue 31: every flag's extremes, and spellings that are not numbers (Python's float() and int()
#: accept "1_0", "+3" and non-ASCII digits; the CLI must not)
EXTREMES = ("-inf", "1e-300", "-1e-300", "1e300", "-1e300", "3e38", "99999999999999999999999", "-99999999999999999999999", "1_0", "+3", "\u0663")
NOT_NUMBERS = ("1_0", "+3", "\u0663", "\u0661\u0660")
#: issue 31: path edge cases for every path flag: a 300-character name (as the file and as a
#: folder), a FIFO, a symlink whose target's folder exists, a device node (a copy of /dev/null)
PATH_EDGES = ("{long}", "{longdir}/x.png", "{fifo}", "{symlink}", "{devnull}")
_PATHLIKE = re.compile(r"\b(file|folder|path|dir)\b|\.(npy|npz|json|yaml|png|jpg|urdf|ply)\b|PATH|DIR|IMG|FILE", re.I)

#: cheap base arguments per command: (positionals, options). {d} = the case folder, {img}, {poses}
#: = fixtures in it. Flags of ``--base-*`` (go2) use BASE_GO2 for mpc.
BASE: dict[tuple[str, ...], tuple[list[str], list[str]]] = {
    ("info",): ([BANANA], []),
    ("scene",): (["stonehenge"], ["--out", "{d}/s.ply"]),
    ("check",): ([BANANA], ["--robot", "sphere:0.01", "--poses", "{poses}"]),
    ("robot", "info"): (["panda"], []),
    ("robot", "fit"): (["panda"], ["--out", "{d}/e.yaml", "--no-png"]),
    ("plan",): ([BANANA], ["--start", "0,0,0", "--goal", "0.05,0,0", "--out", "{d}/p.json", "--time-limit", "1"]),
    ("pick",): ([BANANA], ["--json", "{d}/pick.json"]),
    ("demo",): ([], ["--out", "{d}/demo"]),
    ("view",): ([BANANA], ["--port", "{port}", "--device", "cpu"]),
    ("encode",): (["{img}"], ["--encoder", "thumbnail"]),
    ("render",): ([BANANA], ["--eye", "0,-1,0", "--look-at", "0,0,0", "--width", "16", "--height", "16", "--out", "{d}/r.png"]),
    ("navigate",): ([], ["--target-image", "{img}", "--out", "{d}/n", "--n-splats", "20000", "--tree-nodes", "20", "--n-headings", "2", "--max-steps", "3"]),
    ("mpc",): ([], ["--robot", "panda", "--goal-pose", "0.5,0,0.3,0,1,0,0", "--out", "{d}/m", "--arm-max-steps", "2"]),
    ("eval", "pr"): ([], ["--out", "{d}/o", "--quick"]),
    ("eval", "throughput"): ([], ["--out", "{d}/o", "--quick"]),
    ("eval", "conservatism"): ([], ["--out", "{d}/o", "--quick"]),
    ("eval", "linearization"): ([], ["--out", "{d}/o", "--quick"]),
    ("eval", "reach"): ([], ["--out", "{d}/o", "--quick"]),
    ("eval", "navigate"): ([], ["--out", "{d}/o", "--quick"]),
    ("eval", "arm"): ([], ["--out", "{d}/o", "--quick"]),
    ("eval", "base"): ([], ["--out", "{d}/o", "--quick"]),
    ("eval", "mbm"): ([], ["--out", "{d}/o", "--quick"]),  # exit 2 when the shared MBM data is absent
}
BASE_GO2 = ([], ["--robot", "go2", "--goal", "1,0", "--out", "{d}/m", "--base-max-steps", "2"])
#: parsed but never run here: starts worker subprocesses (an interrupt would orphan them)
PARSE_ONLY = {("eval", "throughput")}


def leaf_parsers(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()):
    """(command path, parser) of every runnable (sub)command."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        yield path, parser
        return
    for a in subs:
        for name, sp in a.choices.items():
            yield from leaf_parsers(sp, path + (name,))


def _pathlike(action: argparse.Action) -> bool:
    text = f"{action.help or ''} {action.metavar or ''} {action.dest}"
    return action.dest in ("out", "scene", "urdf", "images", "status_file") or bool(_PATHLIKE.search(text))


def enumerate_cases() -> list[tuple[tuple[str, ...], str, str]]:
    """(command, flag or positional dest, hostile value) for every value-taking argument."""
    cases = []
    for cmd, p in leaf_parsers(build_parser()):
        for a in p._actions:
            if isinstance(a, argparse._HelpAction) or (a.option_strings and a.nargs == 0):
                continue
            name = a.option_strings[-1] if a.option_strings else a.dest
            if not a.option_strings and a.choices is not None:
                continue  # a nested subcommand name (handled by leaf_parsers)
            values = list(NUMBERS) + list(EXTREMES)
            if _pathlike(a):
                values += ["{missing}", "{adir}", "/proc/splatplan-fuzz/x.out", *PATH_EDGES]
            cases += [(cmd, name, v) for v in values]
    return cases


def build_argv(cmd: tuple[str, ...], name: str, value: str, parser: argparse.ArgumentParser) -> list[str]:
    pos, opts = BASE_GO2 if cmd == ("mpc",) and name.startswith("--base-") else BASE.get(cmd, ([], []))
    pos, opts = list(pos), list(opts)
    pos_actions = [a for a in parser._actions if not a.option_strings]
    if name.startswith("-"):
        nargs = next(a.nargs for a in parser._actions if name in a.option_strings)
        opts += [name] + [value] * (nargs if isinstance(nargs, int) else 1)
    else:
        idx = [a.dest for a in pos_actions].index(name)
        while len(pos) <= idx:
            pos.append("x")
        pos[idx] = value
    # '--flag=-1' keeps a negative number from reading as an option
    out, i = list(cmd) + pos, 0
    while i < len(opts):
        if opts[i].startswith("--") and i + 1 < len(opts) and opts[i + 1].startswith("-") and not opts[i + 1].startswith("--"):
            out.append(f"{opts[i]}={opts[i + 1]}")
            i += 2
        else:
            out.append(opts[i])
            i += 1
    return out


def _fill(argv: list[str], d: Path, port: int) -> list[str]:
    subst = {"{d}": str(d), "{img}": str(d / "img.png"), "{poses}": str(d / "poses.npy"), "{missing}": str(d / "missing" / "x.npy"),
             "{adir}": str(d / "adir"), "{port}": str(port), "{longdir}": str(d / ("D" * 300)), "{long}": str(d / ("L" * 300)),
             "{fifo}": str(d / "fifo"), "{symlink}": str(d / "link"), "{devnull}": str(d / "devnull")}  # fmt: skip
    out = []
    for a in argv:
        for k, v in subst.items():
            a = a.replace(k, v)
        out.append(a)
    return out


def _fixtures(d: Path) -> dict[str, str]:
    from PIL import Image

    d.mkdir(parents=True, exist_ok=True)
    (d / "adir").mkdir(exist_ok=True)
    (d / "linked").mkdir(exist_ok=True)
    if not (d / "fifo").exists():
        os.mkfifo(d / "fifo")
    if not (d / "link").is_symlink():
        (d / "link").symlink_to(d / "linked" / "target")
    if not (d / "devnull").exists():
        try:  # a copy of /dev/null (needs root); else a FIFO stands in for the special file
            os.mknod(d / "devnull", stat.S_IFCHR | 0o666, os.makedev(1, 3))
        except (PermissionError, AttributeError, OSError):
            os.mkfifo(d / "devnull")
    np.save(d / "poses.npy", np.zeros((4, 3)))
    Image.fromarray(np.full((16, 16, 3), 128, np.uint8)).save(d / "img.png")
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in (d / "poses.npy", d / "img.png")} | {"banana": hashlib.sha256(Path(BANANA).read_bytes()).hexdigest()}


def parse_only(argv: list[str]) -> tuple[int | None, str]:
    """(2, stderr) when the parser rejects argv, (None, '') when it accepts it."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            build_parser_cached().parse_args(argv)
        except SystemExit as exc:
            return int(exc.code or 0), err.getvalue()
    return None, ""


_PARSER = None


def build_parser_cached() -> argparse.ArgumentParser:
    global _PARSER
    if _PARSER is None:
        _PARSER = build_parser()
    return _PARSER


_WARM = []


def warm_imports() -> None:
    """Import every splatplan module (and torch/warp/viser through them) before any budgeted run:
    an interrupt in the middle of an import would leave a half-initialised module behind for the
    next in-process run (a real process just exits)."""
    if _WARM:
        return
    import importlib
    import pkgutil

    import splatplan

    for m in pkgutil.walk_packages(splatplan.__path__, "splatplan."):
        if not m.name.endswith("__main__"):
            with contextlib.suppress(ImportError):
                importlib.import_module(m.name)
    for name in ("torch", "warp", "viser", "matplotlib.pyplot", "PIL.Image", "transformers", "yourdfpy", "trimesh", "tqdm"):
        with contextlib.suppress(ImportError):
            importlib.import_module(name)
    _WARM.append(True)


@contextlib.contextmanager
def warnings_as_errors():
    """Every warning the CLI would print is an error here (issue 31: no warning lines), except
    the interpreter's own ResourceWarning (Warp's kernel-cache temp folder) and deprecations of
    third-party libraries, which a user's run never shows."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for cat in (ResourceWarning, DeprecationWarning, PendingDeprecationWarning):
            warnings.simplefilter("ignore", cat)
        yield


def run_in_process(argv: list[str], budget_s: float, cwd: Path) -> tuple[int, str, str, bool, float]:
    """(exit code, stdout, stderr, interrupted by the budget, seconds) of ``main(argv)`` run in
    ``cwd`` (a hostile value read as a relative output path, e.g. ``--status-file 0``, lands there)."""
    out, err = io.StringIO(), io.StringIO()
    old_cwd = os.getcwd()
    fired = []

    def alarm(signum, frame):
        fired.append(True)
        raise KeyboardInterrupt  # what Ctrl-C does: the CLI must clean up and exit 130

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, budget_s)
    t0 = time.perf_counter()
    try:
        os.chdir(cwd)
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), warnings_as_errors():
            try:
                rc = main(argv)
            except SystemExit as exc:
                rc = int(exc.code or 0)
            except KeyboardInterrupt:  # fired outside the CLI's handlers
                rc = 130
            except BaseException as exc:  # noqa: BLE001 - an escape: report it as a traceback
                import traceback

                err.write("Traceback (escaped main):\n" + "".join(traceback.format_exception(exc)))
                rc = -1
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
        os.chdir(old_cwd)
    return rc, out.getvalue(), err.getvalue(), bool(fired), time.perf_counter() - t0


def _json_has_nan(path: Path) -> bool:
    def bad(x):
        raise ValueError(x)

    try:
        json.loads(path.read_text(), parse_constant=bad)
    except ValueError:
        return True
    return False


_TEMP = re.compile(r"^\.(splatplan-|.+\.[A-Za-z0-9_]{8}\b)")


def check_outcome(argv, rc, out, err, interrupted, secs, d: Path, hashes: dict) -> list[str]:
    """Problems with one run (empty = pass)."""
    problems = []
    if interrupted:  # the budget's interrupt landing in a GC callback is printed and swallowed by Python itself
        err = re.sub(r"Exception ignored in: [^\n]*\n(?:.*?\n)*?KeyboardInterrupt: ?\n", "", err)
    if "Traceback" in err:
        problems.append("traceback:\n" + err[-2000:])
    lines = [ln for ln in err.splitlines() if ln.strip()]
    if rc == 2 and not (len(lines) == 1 and lines[0].startswith("splatplan: error: ")):
        problems.append(f"exit 2 without exactly one 'splatplan: error:' line: {err[-1000:]!r}")
    if rc in (0, 1):
        if "RuntimeWarning" in err:
            problems.append(f"RuntimeWarning: {err[-500:]!r}")
        for j in d.rglob("*.json"):
            if _json_has_nan(j):
                problems.append(f"NaN/Inf in {j.name}")
    if rc == 130 and not interrupted:
        problems.append("exit 130 without an interrupt")
    if rc not in (0, 1, 2, 130):
        problems.append(f"exit code {rc}")
    if secs > BUDGET_S + GRACE_S:
        problems.append(f"took {secs:.0f} s (budget {BUDGET_S} s + {GRACE_S} s to stop)")
    for p in d.rglob("*"):
        if _TEMP.match(p.name):
            problems.append(f"temporary file left: {p}")
    if rc == 2:  # rejected: nothing written or left behind (issue 31)
        left = sorted(str(p.relative_to(d)) for p in d.rglob("*") if p.relative_to(d).parts[0] not in FIXTURE_NAMES)
        if left:
            problems.append(f"exit 2 left {left[:5]}")
    if not (d / "fifo").exists() or not stat.S_ISFIFO(os.lstat(d / "fifo").st_mode) or not (d / "link").is_symlink():
        problems.append("a FIFO or a symlink given as a path was replaced")
    if (d / "devnull").exists() and stat.S_ISREG(os.lstat(d / "devnull").st_mode):
        problems.append("the device node given as a path was replaced by a regular file")
    now = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in (d / "poses.npy", d / "img.png")}
    now["banana"] = hashlib.sha256(Path(BANANA).read_bytes()).hexdigest() if "banana" in hashes else None
    if now != hashes:
        problems.append("an input file was modified")
    return problems


#: the fixtures of a case folder (kept between runs)
FIXTURE_NAMES = ("poses.npy", "img.png", "adir", "linked", "fifo", "link", "devnull")


def _reset(d: Path) -> None:
    """Remove everything a run wrote (keep the fixtures)."""
    import shutil

    for p in d.iterdir():
        if p.name not in FIXTURE_NAMES:
            shutil.rmtree(p, ignore_errors=True) if p.is_dir() and not p.is_symlink() else p.unlink(missing_ok=True)
    for sub in ("adir", "linked"):
        for p in (d / sub).iterdir():
            shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)
    if not (d / "devnull").exists() or stat.S_ISREG(os.lstat(d / "devnull").st_mode):
        (d / "devnull").unlink(missing_ok=True)
    _fixtures(d)


ALL_CASES = enumerate_cases()


def test_enumeration_covers_every_command_and_flag():
    parser = build_parser()
    cmds = {c for c, _ in leaf_parsers(parser)}
    assert {("plan",), ("check",), ("view",), ("mpc",), ("eval", "pr"), ("robot", "fit"), ("navigate",)} <= cmds
    flags = {(c, n) for c, n, _ in ALL_CASES}
    assert (("mpc",), "--arm-mppi-n-knots") in flags and (("view",), "--port") in flags
    assert len(flags) > 300  # every value-taking flag of every command


def test_every_case_parses_or_fails_in_one_line(tmp_path):
    """All cases through the parser: a rejection is exactly one 'splatplan: error:' line, exit 2."""
    d = tmp_path / "case"
    _fixtures(d)
    parser = build_parser_cached()
    leaf = dict(leaf_parsers(parser))
    bad = []
    for cmd, name, value in ALL_CASES:
        argv = _fill(build_argv(cmd, name, value, leaf[cmd]), d, 8765)
        rc, err = parse_only(argv)
        if rc is None:
            continue
        lines = [ln for ln in err.splitlines() if ln.strip()]
        if rc != 2 or len(lines) != 1 or not lines[0].startswith("splatplan: error: "):
            bad.append((argv, rc, err))
    assert not bad, f"{len(bad)} bad parser outcomes, e.g. {bad[:3]}"


def _accepted_cases() -> list[tuple[tuple[str, ...], str, str]]:
    parser = build_parser_cached()
    leaf = dict(leaf_parsers(parser))
    d = Path("/nonexistent-fuzz")
    return [c for c in ALL_CASES if c[0] not in PARSE_ONLY and parse_only(_fill(build_argv(c[0], c[1], c[2], leaf[c[0]]), d, 8765))[0] is None]


def _sample(cases, n: int, seed: int):
    if FULL or len(cases) <= n:
        return cases
    return random.Random(seed).sample(cases, n)


_ACCEPTED = None


def accepted() -> list:
    global _ACCEPTED
    if _ACCEPTED is None:
        _ACCEPTED = _accepted_cases()
    return _ACCEPTED


@pytest.mark.skipif(threading.current_thread() is not threading.main_thread() or not hasattr(signal, "setitimer"), reason="needs SIGALRM in the main thread")
def test_accepted_cases_run_cleanly(tmp_path):
    """The cases the parser accepts (a seeded sample, or all with SPLATPLAN_FUZZ_FULL=1) run with
    cheap base arguments under a time budget: one-line error, sane result, or a clean interrupt."""
    from splatplan.viewer.app import free_port

    warm_imports()
    cases = accepted()
    assert cases, "nothing accepted: the base arguments are broken"
    picked = _sample(cases, N_SAMPLE, seed=21)
    d = tmp_path / "case"
    hashes = _fixtures(d)
    parser = build_parser_cached()
    leaf = dict(leaf_parsers(parser))
    failures, summary = [], {}
    for cmd, name, value in picked:
        argv = _fill(build_argv(cmd, name, value, leaf[cmd]), d, free_port())
        rc, out, err, interrupted, secs = run_in_process(argv, BUDGET_S, d)
        probs = check_outcome(argv, rc, out, err, interrupted, secs, d, hashes)
        summary[rc] = summary.get(rc, 0) + 1
        if probs:
            failures.append((" ".join(argv), probs))
        _reset(d)
    report = "\n".join(f"{a}\n    " + "\n    ".join(p) for a, p in failures[:10])
    assert not failures, f"{len(failures)} of {len(picked)} runs failed (exit codes {summary}):\n{report}"


def test_base_arguments_are_valid():
    """Every base command line parses (otherwise its cases would only test the base's own error)."""
    parser = build_parser_cached()
    d = Path("/tmp/fuzz-base")
    for cmd, (pos, opts) in list(BASE.items()) + [(("mpc",), BASE_GO2)]:
        argv = _fill(list(cmd) + pos + opts, d, 8765)
        rc, err = parse_only(argv)
        assert rc is None, (argv, err)
    assert math.isfinite(BUDGET_S)


def _is_numeric(a: argparse.Action) -> bool:
    name = getattr(a.type, "__name__", "")
    return name in ("int", "float") or (a.metavar in ("INT", "FLOAT", "INT|none", "FLOAT|none"))


def test_numeric_flags_refuse_what_is_not_a_number():
    """Issue 31: '1_0', '+3' and non-ASCII digits are numbers to Python, not to the CLI: every
    numeric flag of every command refuses them in one line."""
    parser = build_parser_cached()
    d = Path("/nonexistent-fuzz")
    bad, n = [], 0
    for cmd, p in leaf_parsers(parser):
        for a in p._actions:
            if not (a.option_strings and _is_numeric(a)):
                continue
            n += 1
            for value in NOT_NUMBERS:
                argv = _fill(build_argv(cmd, a.option_strings[-1], value, p), d, 8765)
                rc, err = parse_only(argv)
                if rc != 2 or len(err.strip().splitlines()) != 1:
                    bad.append((" ".join(argv[-2:]), rc, err))
    assert n > 200, n
    assert not bad, f"{len(bad)} accepted, e.g. {bad[:5]}"


def _path_edge_cases() -> list[tuple[tuple[str, ...], str, str]]:
    from splatplan.cli._common import PATH_DESTS

    parser = build_parser_cached()
    leaf = dict(leaf_parsers(parser))
    out = []
    for cmd, name, value in ALL_CASES:
        if value not in PATH_EDGES or cmd in PARSE_ONLY:
            continue
        a = next(x for x in leaf[cmd]._actions if (name in x.option_strings if name.startswith("-") else x.dest == name))
        if a.dest in PATH_DESTS and a.choices is None:
            out.append((cmd, name, value))
    return out


@pytest.mark.skipif(threading.current_thread() is not threading.main_thread() or not hasattr(signal, "setitimer"), reason="needs SIGALRM in the main thread")
def test_path_edge_cases_run_cleanly(tmp_path):
    """Issue 31 (E1, E2, E3 and the FIFO/device 'does not exist'): every path flag of every command
    given a 300-character name, a FIFO, a symlink or a device node. A long name is refused before
    any work (all of them run, each must end within 20 s); the others run as a seeded sample (all
    with SPLATPLAN_FUZZ_FULL=1) under the usual budget: one line, a sane result or a clean
    interrupt; a FIFO, a symlink or a device given is never replaced, nothing is left on exit 2."""
    from splatplan.viewer.app import free_port

    warm_imports()
    cases = _path_edge_cases()
    long_cases = [c for c in cases if c[2].startswith("{long")]
    other = [c for c in cases if not c[2].startswith("{long")]
    assert len(long_cases) > 40, len(long_cases)
    picked = long_cases + _sample(other, N_SAMPLE, seed=31)
    d = tmp_path / "case"
    hashes = _fixtures(d)
    leaf = dict(leaf_parsers(build_parser_cached()))
    failures = []
    for cmd, name, value in picked:
        argv = _fill(build_argv(cmd, name, value, leaf[cmd]), d, free_port())
        long = value.startswith("{long")
        rc, out, err, interrupted, secs = run_in_process(argv, 20.0 if long else BUDGET_S, d)
        probs = check_outcome(argv, rc, out, err, interrupted, secs, d, hashes)
        if long and cmd in BASE and not (rc == 2 and "too long" in err):  # (without a base: its own missing arguments)
            probs.append(f"a 300-character name not refused as too long (exit {rc}): {err[-300:]!r}")
        if probs:
            failures.append((" ".join(a if len(a) < 80 else a[:40] + "..." for a in argv), probs))
        _reset(d)
    report = "\n".join(f"{a}\n    " + "\n    ".join(p) for a, p in failures[:10])
    assert not failures, f"{len(failures)} of {len(picked)} runs failed:\n{report}"


class _ClosedStdout(io.TextIOBase):
    """A stdout whose reader has gone (``| head`` after its lines): every write is a broken pipe."""

    def writable(self) -> bool:
        return True

    def write(self, s: str) -> int:
        raise BrokenPipeError(32, "Broken pipe")

    def fileno(self) -> int:
        raise io.UnsupportedOperation("no file descriptor")


@pytest.mark.skipif(threading.current_thread() is not threading.main_thread() or not hasattr(signal, "setitimer"), reason="needs SIGALRM in the main thread")
def test_closed_stdout_every_command(tmp_path):
    """Every command (with its cheap base arguments) ends quietly when stdout is closed: exit 141
    (or 0/1 when it printed nothing), no traceback or error on stderr; a seeded sample unless
    SPLATPLAN_FUZZ_FULL=1. (A real closed pipe, in a subprocess: tests/test_cli_escapes.py.)"""
    from splatplan.viewer.app import free_port

    warm_imports()
    d = tmp_path / "case"
    _fixtures(d)
    cmds = _sample(sorted(c for c in BASE if c not in PARSE_ONLY and c != ("view",)), 4, seed=141)  # view prints once its server runs
    bad = []
    for cmd in cmds:
        pos, opts = BASE[cmd]
        argv = _fill(list(cmd) + pos + opts, d, free_port())
        err = io.StringIO()
        fired = []

        def alarm(signum, frame):
            fired.append(True)
            raise KeyboardInterrupt

        old = signal.signal(signal.SIGALRM, alarm)
        signal.setitimer(signal.ITIMER_REAL, BUDGET_S)
        cwd = os.getcwd()
        try:
            os.chdir(d)
            with contextlib.redirect_stdout(_ClosedStdout()), contextlib.redirect_stderr(err):
                try:
                    rc = main(argv)
                except SystemExit as exc:
                    rc = int(exc.code or 0)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, old)
            os.chdir(cwd)
        text = err.getvalue()
        quiet = "Traceback" not in text and "BrokenPipe" not in text and "error" not in text  # notes on stderr are fine
        ok = (rc in (0, 1, 141) or (fired and rc == 130)) and quiet
        if not ok:
            bad.append((" ".join(argv), rc, text[-800:]))
        _reset(d)
    assert not bad, bad


#: commands a signal test interrupts (a real process each); view serves until stopped (tested in
#: tests/test_cli_escapes.py), throughput starts worker processes of its own
SIGNAL_CMDS = sorted(c for c in BASE if c not in PARSE_ONLY and c != ("view",))


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_during_every_long_command(sig, tmp_path):
    """Issue 31 (E11): SIGINT or SIGTERM at a seeded moment of every command (a real process, its
    cheap base arguments; a seeded sample of 2, all with SPLATPLAN_FUZZ_FULL=1): exit 130 / 143
    with one line and no traceback (or it finished first: 0, 1), no temporary file, and an
    interrupted run leaves no output behind unless it says how to resume."""
    import subprocess
    import sys

    from splatplan.viewer.app import free_port

    cmds = SIGNAL_CMDS if FULL else _sample(SIGNAL_CMDS, 2, seed=int(sig))
    rng = random.Random(int(sig))
    want = 130 if sig == signal.SIGINT else 143
    env = {**os.environ, "SPLATPLAN_NO_TQDM": "1", "PYTHONWARNINGS": "error::RuntimeWarning,error::UserWarning"}
    src = str(Path(__file__).resolve().parents[1] / "src")
    env["PYTHONPATH"] = src + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    bad = []
    for cmd in cmds:
        d = tmp_path / "_".join(cmd)
        hashes = _fixtures(d)
        pos, opts = BASE[cmd]
        argv = _fill(list(cmd) + pos + opts, d, free_port())
        delay = rng.uniform(2.0, 8.0)
        p = subprocess.Popen([sys.executable, "-m", "splatplan.cli", *argv], cwd=d, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
        try:
            try:
                p.wait(timeout=delay)
            except subprocess.TimeoutExpired:
                p.send_signal(sig)
            out, err = p.communicate(timeout=120)
        finally:
            if p.poll() is None:
                p.kill()
                p.wait()
        rc = p.returncode
        probs = []
        # -sig: the signal came after the command had ended, while the interpreter shut down (Python
        # restores the default handlers then): a shell reports 128 + sig, and the outputs are complete
        if rc not in (0, 1, 2, want, -int(sig)):
            probs.append(f"exit {rc}")
        if "Traceback" in err or "Warning" in err:
            probs.append(f"traceback or warning: {err[-600:]!r}")
        last = ([ln for ln in err.splitlines() if ln.strip()] or [""])[-1]
        if rc == want and not last.startswith(f"splatplan: {'interrupted' if want == 130 else 'terminated'}"):
            probs.append(f"no closing line: {err[-300:]!r}")
        left = sorted(str(q.relative_to(d)) for q in d.rglob("*") if q.relative_to(d).parts[0] not in FIXTURE_NAMES)
        if rc in (2, want) and left and "resume" not in err:
            probs.append(f"exit {rc} left {left[:5]}")
        probs += [f"temporary file left: {q}" for q in d.rglob("*") if _TEMP.match(q.name)]
        if {q.name: hashlib.sha256(q.read_bytes()).hexdigest() for q in (d / "poses.npy", d / "img.png")} != {k: v for k, v in hashes.items() if k != "banana"}:
            probs.append("an input file was modified")
        if probs:
            bad.append(f"{' '.join(argv[:3])} (signal after {delay:.1f} s): " + "; ".join(probs))
    assert not bad, "\n".join(bad)
