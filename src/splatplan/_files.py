"""Atomic output files and YAML input, shared by the library (robot YAMLs, MoveIt scenes, sweep
specs) and the CLI.

Frames and units do not apply; this is plumbing. Scene files use
:func:`splatplan.scenes.io_ply.atomic_write`, which keeps an existing file's mode.
"""

from __future__ import annotations

import errno
import os
import shutil
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path

from .errors import SplatplanError


def current_umask() -> int:
    """The process umask (read by setting and restoring it)."""
    m = os.umask(0o022)
    os.umask(m)
    return m


def path_error(path, exc: OSError) -> str:
    """One line for an ``OSError`` of ``path`` (any kind: missing, too long, not a folder, no
    space, read-only, ...): the path the user gave and the reason, lower-case."""
    reason = exc.strerror or str(exc) or exc.__class__.__name__
    reason = reason[:1].lower() + reason[1:]
    return f"{path}: {reason}"


def _stat(path: Path, follow: bool = True):
    """``os.stat`` of ``path`` or None when nothing is there; any other OSError (a name too long,
    a component that is a file, no permission) is one :class:`SplatplanError` naming the path."""
    try:
        return os.stat(path, follow_symlinks=follow)
    except (FileNotFoundError, NotADirectoryError):
        return None
    except OSError as exc:
        raise SplatplanError(f"cannot write {path_error(path, exc)}") from None


def output_target(path: str | Path) -> tuple[Path, bool]:
    """Where an output named ``path`` goes: (the file to replace, whether it is special).

    The one rule of every output file: a symlink is followed (its target is replaced, the link
    stays); an existing non-regular target (``/dev/null``, a FIFO, a terminal) is written directly,
    never replaced by a rename (``special`` = True); a folder is refused; otherwise the file (new
    or existing) is replaced atomically. A name the file system cannot hold (too long) or a parent
    that does not exist is one :class:`SplatplanError` naming the path given.
    """
    given = Path(path)
    lst = _stat(given, follow=False)
    dest = Path(os.path.realpath(given)) if lst is not None and stat.S_ISLNK(lst.st_mode) else given
    st = _stat(dest)
    if st is not None:
        if stat.S_ISDIR(st.st_mode):
            raise SplatplanError(f"output {given} is a directory; give a file path")
        if not stat.S_ISREG(st.st_mode):
            return dest, True
    parent = dest.parent
    pst = _stat(parent)
    if pst is None:
        raise SplatplanError(f"output folder {parent} does not exist")
    if not stat.S_ISDIR(pst.st_mode):
        raise SplatplanError(f"output folder {parent} is not a folder")
    limit = _name_max(parent)
    if len(os.fsencode(dest.name)) > limit:
        raise SplatplanError(f"cannot write {given}: file name too long ({len(os.fsencode(dest.name))} bytes, the limit is {limit})")
    return dest, False


def _name_max(folder: Path) -> int:
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):
        return 255


def write_special(src: Path, dest: Path, given: str | Path | None = None) -> None:
    """Copy the finished file ``src`` into the existing non-regular file ``dest`` (a device node or
    a FIFO): written directly, never replaced. A FIFO without a reader, a full device (``/dev/full``)
    or any other write error is one :class:`SplatplanError` naming the path given."""
    given = dest if given is None else given
    flags = os.O_WRONLY | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(dest, flags)
    except OSError as exc:
        if exc.errno == errno.ENXIO:
            raise SplatplanError(f"cannot write {given}: a FIFO with no reader") from None
        raise SplatplanError(f"cannot write {path_error(given, exc)}") from None
    try:
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        with open(src, "rb") as f:
            while chunk := f.read(1 << 20):
                view = memoryview(chunk)
                while view:
                    n = os.write(fd, view)
                    view = view[n:]
    except OSError as exc:
        if exc.errno == errno.ENOSPC:
            raise SplatplanError(f"cannot write {given}: no space left on the device") from None
        raise SplatplanError(f"cannot write {path_error(given, exc)}") from None
    finally:
        os.close(fd)


def publish(tmp: str | Path, path: str | Path, mode: int | None = None) -> None:
    """Move the finished temp file ``tmp`` to the output ``path`` by the rule of
    :func:`output_target` (a rename for files, a direct write for devices and FIFOs); ``mode``
    (default 0666 minus the umask) for a regular file."""
    dest, special = output_target(path)
    if special:
        write_special(Path(tmp), dest, path)
        os.unlink(tmp)
        return
    try:
        os.chmod(tmp, (0o666 & ~current_umask()) if mode is None else mode)
        try:
            os.replace(tmp, dest)
        except OSError as exc:
            if exc.errno != errno.EXDEV:
                raise
            # a symlink's target on another file system: copy next to it, then rename there
            fd, near = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=dest.suffix, dir=dest.parent)
            os.close(fd)
            try:
                shutil.copyfile(tmp, near)
                os.chmod(near, (0o666 & ~current_umask()) if mode is None else mode)
                os.replace(near, dest)
            finally:
                if os.path.exists(near):
                    os.unlink(near)
            os.unlink(tmp)
    except OSError as exc:
        if exc.errno == errno.ENOSPC:
            raise SplatplanError(f"cannot write {path}: no space left on the device") from None
        raise SplatplanError(f"cannot write {path_error(path, exc)}") from None


@contextmanager
def atomic_path(path: str | Path):
    """Yield a temp path in the destination folder; move it over ``path`` only on success.

    The final file gets the permissions a plain ``open(path, "w")`` would give (0666 minus the
    umask), not mkstemp's 0600. The temp file is removed on any exception, KeyboardInterrupt and
    SystemExit included (``main`` turns SIGTERM into SystemExit so this runs then too). The target
    follows :func:`output_target`: a symlink's target is replaced; an existing device node or FIFO
    (``/dev/null``) is written directly (its temp file then lives in the system's temp folder).
    """
    given = Path(path)
    dest, special = output_target(given)
    folder = tempfile.gettempdir() if special else (dest.parent or ".")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=dest.suffix, dir=folder)
    except OSError as exc:  # name the path the caller gave, not the temp file
        raise SplatplanError(f"cannot write {given}: {exc.strerror or exc}") from None
    os.close(fd)
    try:
        try:
            yield Path(tmp)
        except OSError as exc:
            if exc.filename is not None and os.path.abspath(exc.filename) == os.path.abspath(tmp):
                raise SplatplanError(f"cannot write {given}: {exc.strerror or exc}") from None
            raise
        publish(tmp, given)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


#: what a non-regular file is, for messages
_KINDS = ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISSOCK, "a socket"))


def file_kind(mode: int) -> str:
    """'a character device', 'a FIFO (named pipe)', ... for a non-regular ``st_mode``."""
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def existing_file(path: str | Path, what: str, kind: str, error: type[SplatplanError] = SplatplanError,
                  max_bytes: int | None = None) -> Path:
    """``path`` as a Path when it is a regular file (of at most ``max_bytes``, when given); else one
    ``error`` line naming ``what`` (e.g. "poses file") and the path: a folder, nothing there, a
    device node or FIFO (never opened: reading ``/dev/zero`` or a FIFO would not end), a name the
    file system cannot hold, or a file over the size limit (``kind``: what was expected, e.g. "a
    YAML file")."""
    path = Path(path)
    try:
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        raise error(f"{what} {path} does not exist") from None
    except OSError as exc:
        raise error(f"{what} {path_error(path, exc)}") from None
    if stat.S_ISDIR(st.st_mode):
        raise error(f"{what} {path} is a directory; expected {kind}")
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{what} {path} is {file_kind(st.st_mode)}, not a regular file; expected {kind}")
    if max_bytes is not None and st.st_size > max_bytes:
        raise error(f"{what} {path} is {st.st_size:,} bytes, over the {max_bytes:,}-byte limit for {kind}")
    return path


#: the largest text input (YAML, URDF) read whole: far above any real one
MAX_TEXT_BYTES = 64 * 1024**2


def read_bounded(path: str | Path, what: str, kind: str, max_bytes: int, error: type[SplatplanError] = SplatplanError) -> bytes:
    """The bytes of a regular file of at most ``max_bytes`` (checked before reading, and again while
    reading: a file that grows is cut off), or one ``error`` line (see :func:`existing_file`)."""
    p = existing_file(path, what, kind, error, max_bytes=max_bytes)
    try:
        with open(p, "rb") as f:
            data = f.read(max_bytes + 1)
    except OSError as exc:
        raise error(f"{what} {path_error(path, exc)}") from None
    if len(data) > max_bytes:
        raise error(f"{what} {path} is over the {max_bytes:,}-byte limit for {kind}")
    return data


def read_yaml(path: str | Path, what: str, error: type[SplatplanError] = SplatplanError):
    """Parse a YAML file; a missing file, a folder, a syntax error or binary data is one ``error``
    line naming ``what`` (e.g. "MoveIt YAML") and the path (with the line and column of a syntax
    error). Needs PyYAML (a core dependency)."""
    import yaml

    data = read_bounded(path, what, "a YAML file", MAX_TEXT_BYTES, error)
    try:
        doc = yaml.safe_load(data.decode())
    except RecursionError:
        raise error(f"{what} {path}: nested too deeply (the limit is {MAX_YAML_DEPTH} levels)") from None
    except yaml.YAMLError as exc:
        where = getattr(exc, "problem_mark", None)
        at = f" at line {where.line + 1}, column {where.column + 1}" if where is not None else ""
        problem = getattr(exc, "problem", None) or exc.__class__.__name__
        raise error(f"{what} {path}: not valid YAML{at} ({problem})") from None
    except UnicodeDecodeError:
        raise error(f"{what} {path}: not a text (YAML) file") from None
    except ValueError as exc:  # an integer of more than 4,300 digits (Python's limit on int())
        raise error(f"{what} {path}: not valid YAML (an integer of more than 4,300 digits)") from None
    problem = yaml_problem(doc)
    if problem:
        raise error(f"{what} {path}: {problem}")
    return doc


#: the deepest nesting of lists and mappings a YAML input may have (real ones have under 10)
MAX_YAML_DEPTH = 64
#: the largest integer a YAML input may hold (counts, seeds and sizes fit in 64 bits)
MAX_YAML_INT = 2**63 - 1


def yaml_problem(doc) -> str | None:
    """Why a parsed YAML document is outside what any reader accepts (nested deeper than
    :data:`MAX_YAML_DEPTH`, an integer beyond 64 bits, NaN or Inf where a number is read later is
    left to the field's own range), or None. Walks iteratively (no recursion limit)."""
    stack = [(doc, 0, "")]
    while stack:
        node, depth, where = stack.pop()
        if depth > MAX_YAML_DEPTH:
            return f"nested too deeply at {where or 'the top'} (the limit is {MAX_YAML_DEPTH} levels)"
        if isinstance(node, dict):
            for k, v in node.items():
                if isinstance(k, int) and not isinstance(k, bool) and abs(k) > MAX_YAML_INT:
                    return f"a key at {where or 'the top'} is an integer beyond 64 bits"
                stack.append((v, depth + 1, f"{where}.{k}" if where else str(k)))
        elif isinstance(node, list):
            stack.extend((v, depth + 1, f"{where}[{i}]") for i, v in enumerate(node))
        elif isinstance(node, int) and not isinstance(node, bool) and abs(node) > MAX_YAML_INT:
            return f"{where or 'the value'}: an integer beyond 64 bits"
    return None
