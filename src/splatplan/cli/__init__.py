"""Command-line interface. Thin: parse, call the library, print, exit codes.

Exit codes: 0 success, 1 no result within the budget (e.g. ``plan`` found no path), 2 bad input
or impossible request (one-line message, no traceback), 130 interrupted (Ctrl-C), 141 stdout
closed early (``| head``; quiet), 143 terminated (SIGTERM). Output files are written atomically,
with the umask's permissions; an interrupted command leaves no partial output or temporary file
behind.

Flags: config fields become flags (``_common.add_config_args``) and carry the fields' declared
ranges (:mod:`splatplan._config`); plain flags take ``type=`` validators from ``_common``
(``int_arg``, ``float_arg``, ``SEED``, ``POSITIVE_INT``, ``PORT``). Every usage error is one line
(``_common.Parser``); ``main`` returns 2 for it. ``tests/test_cli_fuzz.py`` fuzzes every command and
flag found in this parser, so a new command is covered as soon as it is registered here. ``--device`` means the same in every
subcommand (``auto`` = CUDA when present, else CPU) and is checked before any work starts.

One module per group of subcommands; each exposes ``register(sub, eval_sub)`` where ``sub`` is
the top-level subparsers object and ``eval_sub`` the subparsers of ``splatplan eval``. Add a new
module to ``_MODULES`` to add commands.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from ..errors import SplatplanError

#: Subcommand modules (relative to this package), in the order of ``splatplan --help``.
_MODULES = (
    "scenes",
    "pick",
    "check",
    "robot",
    "plan",
    "demo",
    "eval",
    "view",
    "encode",
    "render",
    "tasks",
    "mpc",
    "sweep",
)


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__
    from ._flags import Parser

    p = Parser(prog="splatplan", description="Collision-aware motion planning in Gaussian-splat scenes.")
    p.add_argument("--version", action="version", version=f"splatplan {__version__}")
    sub = p.add_subparsers(dest="cmd", required=True, metavar="COMMAND")
    ev = sub.add_parser("eval", help="the paper's studies and the robot studies")
    eval_sub = ev.add_subparsers(dest="study", required=True, metavar="STUDY")
    for name in _MODULES:
        importlib.import_module(f".{name}", __name__).register(sub, eval_sub)
    from ._flags import allow_negative_values

    allow_negative_values(p)  # every coordinate flag of every command accepts a leading minus
    return p


def main(argv: list[str] | None = None) -> int:
    from ._outputs import CREATED_DIRS, remove_created_empty_dirs
    from ._process import headless_matplotlib

    headless_matplotlib()
    CREATED_DIRS.clear()
    from ._outputs import OUT_BEFORE

    OUT_BEFORE.clear()
    engine = sys.modules.get("splatplan.eval.engine")
    if engine is not None:
        engine.RESUMABLE.clear()
    try:
        rc = _main(argv)
        sys.stdout.flush()  # a closed pipe raises here, not at interpreter exit
    except BrokenPipeError:
        rc = _broken_pipe()
    if rc not in (0, 1, 141):  # 1: ran, with a negative answer (results written); else rejected, failed or interrupted
        from ._outputs import remove_new_outputs

        engine = sys.modules.get("splatplan.eval.engine")
        remove_new_outputs(keep=list(getattr(engine, "RESUMABLE", [])))
        remove_created_empty_dirs()
    CREATED_DIRS.clear()
    from ._outputs import OUT_BEFORE

    OUT_BEFORE.clear()
    if argv is None:  # the process's own entry (console script, python -m): its exit is this rc
        _exit_on_signal(rc)
    return rc


def _exit_on_signal(rc: int) -> None:
    """After the command has ended (outputs written or removed), a SIGINT / SIGTERM during the
    interpreter's shutdown (seconds with Warp and torch loaded) exits with the command's code at
    once, instead of killing the process by the signal (a shell would report 143 for a run that
    had finished)."""
    import os
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return

    def leave(signum, frame):
        os._exit(rc)

    for s in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(s) is not signal.SIG_IGN:
            signal.signal(s, leave)


def _broken_pipe() -> int:
    """stdout was closed early (``splatplan ... | head -1``): end quietly (no message, exit 141 as
    for a process ended by SIGPIPE; outputs already written stay, temp files are gone). Python's recommended pattern: point stdout at devnull so the interpreter's final flush
    does not raise again (https://docs.python.org/3/library/signal.html#note-on-sigpipe)."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # stdout without a file descriptor (captured in tests)
        pass
    return 141  # 128 + SIGPIPE: what a shell reports for a writer that its reader left


#: One line per file error that means bad input (exit 2).
_FILE_ERRORS = {
    FileNotFoundError: "{}: no such file",
    IsADirectoryError: "{}: is a directory, expected a file",
    PermissionError: "permission denied: {}",
}


def _resume_hint() -> str:
    """'; the finished tasks are kept in LOG: rerun the same command to resume' when an
    interrupted run wrote a results log (:data:`splatplan.eval.engine.RESUMABLE`), else ''."""
    engine = sys.modules.get("splatplan.eval.engine")
    logs = [p for p in getattr(engine, "RESUMABLE", []) if p.exists()]
    if not logs:
        return ""
    return f"; the finished tasks are kept in {', '.join(map(str, logs))}: rerun the same command to resume"


def _leaf(parser: argparse.ArgumentParser, args: argparse.Namespace) -> argparse.ArgumentParser:
    """The (sub)command parser that parsed ``args`` (for its flags' help texts)."""
    p = parser
    while True:
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]  # noqa: SLF001
        if not subs:
            return p
        name = getattr(args, subs[0].dest, None)
        if name not in subs[0].choices:
            return p
        p = subs[0].choices[name]


#: errno values of an OSError without a file name that still mean "the output cannot be written"
_PATHLESS_ERRNOS = {28, 30, 122}  # ENOSPC, EROFS, EDQUOT


class _HeldNotes:
    """stderr while a command runs: ``note:`` lines are held until the next other output (or the
    end of a run that succeeds), and dropped when the run ends in ``splatplan: error:``, so a
    rejected command prints exactly one line (no note line before the error)."""

    _PREFIXES = ("note:", "splatplan:")

    def __init__(self, target) -> None:
        self.target, self.buf = target, ""
        self.held: list[str] = []  # note lines held back until the command ends

    def _maybe_prefix(self, b: str) -> bool:
        return any(b.startswith(p) or p.startswith(b) for p in self._PREFIXES)

    def write(self, s: str) -> int:
        self.buf += s
        while self.buf:
            if "\n" in self.buf:
                line, self.buf = self.buf.split("\n", 1)
                self._line(line + "\n")
            elif not self._maybe_prefix(self.buf):  # a progress bar's partial line: now
                self._release()
                self.target.write(self.buf)
                self.buf = ""
            else:
                break
        return len(s)

    def _line(self, line: str) -> None:
        if line.startswith("note:"):
            self.held.append(line)
            return
        if line.startswith("splatplan: error:"):
            self.held.clear()
        else:
            self._release()
        self.target.write(line)

    def _release(self) -> None:
        for line in self.held:
            self.target.write(line)
        self.held.clear()

    def finish(self, keep: bool) -> None:
        """End of the command: write the held notes (``keep``) or drop them, then any partial line."""
        if keep:
            self._release()
        self.held.clear()
        if self.buf:
            self.target.write(self.buf)
            self.buf = ""
        self.target.flush()

    def flush(self) -> None:
        self.target.flush()

    def __getattr__(self, name):  # fileno, isatty, encoding, ...
        return getattr(self.target, name)


class _ReleasingStdout:
    """stdout while a command runs: the held notes are written before any output, in order."""

    def __init__(self, target, held: _HeldNotes) -> None:
        self.target, self.notes = target, held

    def write(self, s: str) -> int:
        if s and self.notes.held:
            self.notes._release()  # noqa: SLF001
            self.notes.target.flush()
        return self.target.write(s)

    def __getattr__(self, name):
        return getattr(self.target, name)


def _main(argv: list[str] | None) -> int:
    held = _HeldNotes(sys.stderr)
    out = _ReleasingStdout(sys.stdout, held)
    sys.stderr, sys.stdout = held, out
    rc = 2
    try:
        rc = _run(argv)
        return rc
    finally:
        if sys.stderr is held:
            sys.stderr = held.target
        if sys.stdout is out:
            sys.stdout = out.target
        held.finish(keep=rc != 2)


def _run(argv: list[str] | None) -> int:
    from ._flags import UsageError, check_device
    from ._process import Terminated, cli_signal_handlers, received_signal

    with cli_signal_handlers():  # Ctrl-C / SIGTERM unwind through every finally (no stray temp files)
        try:
            try:
                parser = build_parser()
                args = parser.parse_args(argv)  # --help / --version exit through argparse's SystemExit
            except UsageError as exc:  # already printed as one line
                return int(exc.code or 0)
            from ._flags import reject_nan_flags
            from ._inputs import check_paths

            reject_nan_flags(args)
            check_paths(args, _leaf(parser, args))
            if getattr(args, "device", None) is not None:
                args.device = check_device(args.device)  # one meaning everywhere: auto -> cuda:0 or cpu
            return int(args.func(args) or 0)
        except SplatplanError as exc:
            print(f"splatplan: error: {exc}", file=sys.stderr)
            return 2
        except (FileNotFoundError, IsADirectoryError, PermissionError) as exc:
            msg = next(m for t, m in _FILE_ERRORS.items() if isinstance(exc, t))
            print(f"splatplan: error: {msg.format(exc.filename or exc)}", file=sys.stderr)
            return 2
        except OSError as exc:
            # the one path-error rule: any OSError of a path (a name too long, not a folder, no
            # space, a read-only file system, ...) is one line naming the path and the reason
            if exc.filename is None and exc.errno not in _PATHLESS_ERRNOS:
                raise
            from .._files import path_error

            what = path_error(exc.filename, exc) if exc.filename is not None else (exc.strerror or str(exc))
            print(f"splatplan: error: {' '.join(what.split())}", file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print(f"splatplan: interrupted{_resume_hint()}", file=sys.stderr)
            return 130
        except Terminated as exc:
            print(f"splatplan: terminated{_resume_hint()}", file=sys.stderr)
            return int(exc.code or 0)
        except MemoryError:
            print("splatplan: error: out of memory; try a smaller batch or --device cuda", file=sys.stderr)
            return 2
        except Exception:
            sig = received_signal()
            if sig is None:
                raise
            # a Ctrl-C / SIGTERM that native code turned into another error (a C extension whose
            # import it interrupted raises ImportError): the interruption it is
            import signal

            term = sig == signal.SIGTERM
            print(f"splatplan: {'terminated' if term else 'interrupted'}{_resume_hint()}", file=sys.stderr)
            return 128 + int(sig) if term else 130
