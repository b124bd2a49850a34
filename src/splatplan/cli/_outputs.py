"""What a command writes: atomic output files and folders, valid JSON, and the clean-up of a run
that fails or is interrupted (its outputs appear together or not at all)."""

from __future__ import annotations

import contextlib
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Sequence

from .._files import atomic_path, publish
from .._json import dumps_json, json_safe, write_json
from ..errors import SplatplanError

__all__ = [
    "CREATED_DIRS", "OUT_BEFORE", "atomic_dir", "atomic_path", "dumps_json", "json_safe", "move_into", "out_dir", "remove_created_empty_dirs",
    "remove_new_outputs", "write_json",
]  # fmt: skip


@contextmanager
def atomic_dir(folder: str | Path):
    """Yield a fresh temp folder inside ``folder``; the caller moves finished files out of it
    (see :func:`move_into`). The temp folder and anything left in it are always removed."""
    folder = Path(folder)
    if not folder.is_dir():
        raise SplatplanError(f"output folder {folder} does not exist")
    try:
        tmp = tempfile.mkdtemp(prefix=".splatplan-", dir=folder)
    except OSError as exc:  # name the folder the user gave, not the temp folder
        raise SplatplanError(f"cannot write into {folder}: {exc.strerror or exc}") from None
    try:
        yield Path(tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def move_into(src: Path, dest: str | Path) -> None:
    """Move a finished temp file to ``dest`` (atomic on one file system), permissions per umask,
    by the one output rule (:func:`splatplan._files.publish`: symlinks followed, devices written)."""
    publish(src, dest)


#: Output folders this process created (deepest last); a command that fails removes the empty ones.
CREATED_DIRS: list[Path] = []


def out_dir(path: str) -> Path:
    d = Path(path)
    if d.exists() and not d.is_dir():
        raise SplatplanError(f"output folder {d} exists and is not a folder")
    new = []
    a = d.absolute()
    while not a.exists():
        new.append(a)
        a = a.parent
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SplatplanError(f"cannot create output folder {d}: {exc.strerror}") from None
    CREATED_DIRS.extend(reversed(new))
    try:
        OUT_BEFORE.setdefault(d.resolve(), {e.name for e in d.iterdir()})
    except OSError:
        pass
    return d


#: Output folders of this process and the names they held before it wrote there: a run that ends
#: in an error or an interrupt removes what it added (:func:`remove_new_outputs`)
OUT_BEFORE: dict[Path, set[str]] = {}


def remove_new_outputs(keep: Sequence[str | Path] = ()) -> None:
    """Remove the entries this run added to its output folders (a rejected or interrupted run
    leaves nothing: its outputs appear together or not at all), except ``keep`` (resumable results
    logs, which the closing line names) and their ``.arrays`` folders."""
    kept = {Path(k).resolve() for k in keep}
    kept |= {Path(f"{k}.arrays") for k in kept}
    while OUT_BEFORE:
        d, before = OUT_BEFORE.popitem()
        try:
            entries = list(d.iterdir())
        except OSError:
            continue
        for e in entries:
            if e.name in before or e.resolve() in kept:
                continue
            if e.is_dir() and not e.is_symlink():
                shutil.rmtree(e, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    e.unlink()


def remove_created_empty_dirs() -> None:
    """Remove the output folders this process created that are still empty (deepest first): a
    command rejected after making its folder leaves nothing behind."""
    while CREATED_DIRS:
        d = CREATED_DIRS.pop()
        try:
            d.rmdir()  # only when empty
        except OSError:
            pass
