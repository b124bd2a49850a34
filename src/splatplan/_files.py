"""Atomic output files and YAML input, shared by the library (robot YAMLs, MoveIt scenes, sweep
specs) and the CLI.

Frames and units do not apply; this is plumbing. Scene files use
:func:`splatplan.scenes.io_ply.atomic_write`, which keeps an existing file's mode.
"""

from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

from .errors import SplatplanError


def _umask() -> int:
    """The process umask (read by setting and restoring it)."""
    m = os.umask(0o022)
    os.umask(m)
    return m


@contextmanager
def atomic_path(path: str | Path):
    """Yield a temp path in the destination folder; move it over ``path`` only on success.

    The final file gets the permissions a plain ``open(path, "w")`` would give (0666 minus the
    umask), not mkstemp's 0600. The temp file is removed on any exception, KeyboardInterrupt and
    SystemExit included (``main`` turns SIGTERM into SystemExit so this runs then too).
    """
    dest = Path(path)
    if dest.is_dir():
        raise SplatplanError(f"output {dest} is a directory; give a file path")
    if dest.parent and not dest.parent.exists():
        raise SplatplanError(f"output folder {dest.parent} does not exist")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=dest.suffix, dir=dest.parent or ".")
    except OSError as exc:  # name the path the caller gave, not the temp file
        raise SplatplanError(f"cannot write {dest}: {exc.strerror or exc}") from None
    os.close(fd)
    try:
        try:
            yield Path(tmp)
        except OSError as exc:
            if exc.filename is not None and os.path.abspath(exc.filename) == os.path.abspath(tmp):
                raise SplatplanError(f"cannot write {dest}: {exc.strerror or exc}") from None
            raise
        try:
            os.chmod(tmp, 0o666 & ~_umask())
            os.replace(tmp, dest)
        except OSError as exc:
            raise SplatplanError(f"cannot write {dest}: {exc.strerror or exc}") from None
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def existing_file(path: str | Path, what: str, kind: str, error: type[SplatplanError] = SplatplanError) -> Path:
    """``path`` as a Path when it is a file; else one ``error`` line naming ``what`` (e.g. "poses
    file") and the path: a folder, or nothing there (``kind``: what was expected, e.g. "a YAML file")."""
    path = Path(path)
    if path.is_dir():
        raise error(f"{what} {path} is a directory; expected {kind}")
    if not path.is_file():
        raise error(f"{what} {path} does not exist")
    return path


def read_yaml(path: str | Path, what: str, error: type[SplatplanError] = SplatplanError):
    """Parse a YAML file; a missing file, a folder, a syntax error or binary data is one ``error``
    line naming ``what`` (e.g. "MoveIt YAML") and the path (with the line and column of a syntax
    error). Needs PyYAML (a core dependency)."""
    import yaml

    path = existing_file(path, what, "a YAML file", error)
    try:
        return yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None)
        at = f" at line {where.line + 1}, column {where.column + 1}" if where is not None else ""
        problem = getattr(exc, "problem", None) or exc.__class__.__name__
        raise error(f"{what} {path}: not valid YAML{at} ({problem})") from None
    except UnicodeDecodeError:
        raise error(f"{what} {path}: not a text (YAML) file") from None
