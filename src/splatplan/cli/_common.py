"""Shared CLI helpers: argument parsing of vectors/robots/poses, atomic output files, config flags.

Every subcommand module imports from here; nothing here imports a heavy library at module level.
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import json
import os
import re
import sys
import tempfile
import typing
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..errors import SplatplanError

ROBOT_HELP = "robot link: 'sphere:R' or 'ellipsoid:A,B,C' (semi-axes, scene units)"

def parse_robot(spec: str) -> np.ndarray:
    """'sphere:R' or 'ellipsoid:A,B,C' -> semi-axes (3,) float64."""
    kind, _, rest = spec.partition(":")
    try:
        vals = [float(v) for v in rest.split(",")] if rest else []
    except ValueError:
        raise SplatplanError(f"--robot {spec!r}: numbers expected after ':' ({ROBOT_HELP})") from None
    if kind == "sphere" and len(vals) == 1:
        axes = np.full(3, vals[0])
    elif kind == "ellipsoid" and len(vals) == 3:
        axes = np.asarray(vals)
    else:
        raise SplatplanError(f"--robot {spec!r} not understood: {ROBOT_HELP}")
    if not np.all(np.isfinite(axes)) or np.any(axes <= 0):
        raise SplatplanError(f"--robot {spec!r}: sizes must be finite and > 0")
    return axes


def parse_vec3(text: str, what: str) -> np.ndarray:
    try:
        v = np.asarray([float(x) for x in text.split(",")], dtype=np.float64)
    except ValueError:
        raise SplatplanError(f"{what} {text!r}: expected three comma-separated numbers X,Y,Z") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise SplatplanError(f"{what} {text!r}: expected three finite comma-separated numbers X,Y,Z")
    return v


def load_poses(path: str) -> tuple[np.ndarray, np.ndarray | None]:
    """POSES.npy of shape (B, 3) centres or (B, 7) centre + wxyz quaternion."""
    p = Path(path)
    if not p.is_file():
        raise SplatplanError(f"poses file {path} does not exist")
    try:
        arr = np.load(p, allow_pickle=False)
    except Exception as exc:  # numpy raises several types for broken files
        raise SplatplanError(f"poses file {path} is not a readable .npy array ({exc.__class__.__name__}: {exc})") from None
    if not np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.complexfloating):
        raise SplatplanError(f"poses file {path}: expected a real numeric array, got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] not in (3, 7):
        raise SplatplanError(f"poses file {path}: expected shape (B, 3) centres or (B, 7) centre + wxyz quaternion, got {arr.shape}")
    arr = arr.astype(np.float64)
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise SplatplanError(f"poses file {path}: {int(bad.sum())} row(s) contain NaN or Inf (first: row {int(np.argmax(bad))})")
    if arr.shape[1] == 7:
        q = arr[:, 3:]
        if np.any(np.linalg.norm(q, axis=1) < 1e-8):
            raise SplatplanError(f"poses file {path}: zero quaternion in row {int(np.argmax(np.linalg.norm(q, axis=1) < 1e-8))}")
        return arr[:, :3], q
    return arr, None


@contextmanager
def atomic_path(path: str | Path):
    """Yield a temp path in the destination folder; move it over ``path`` only on success."""
    dest = Path(path)
    if dest.parent and not dest.parent.exists():
        raise SplatplanError(f"output folder {dest.parent} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=dest.suffix, dir=dest.parent or ".")
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, dest)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_json(path: str | Path, obj) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=2) + "\n")


def _out_dir(path: str) -> Path:
    d = Path(path)
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SplatplanError(f"cannot create output folder {d}: {exc.strerror}") from None
    return d


def _load(path: str, filter_floaters: bool = True):
    from ..scenes.load import load_scene

    return load_scene(path, filter_floaters=filter_floaters)




# ---------------------------------------------------------------------------- config dataclasses -> flags
def field_docs(cls) -> dict[str, str]:
    """The ``#:`` comment above each field of a dataclass (joined when it spans several lines)."""
    docs: dict[str, str] = {}
    try:
        lines = inspect.getsource(cls).splitlines()
    except (OSError, TypeError):
        return docs
    pending: list[str] = []
    for line in lines:
        s = line.strip()
        if s.startswith("#:"):
            pending.append(s[2:].strip())
            continue
        m = re.match(r"^([A-Za-z_][A-Za-z0-9_]*)\s*:", s)
        if m and pending:
            docs[m.group(1)] = " ".join(pending)
        if not s.startswith("#"):
            pending = []
    return docs


def add_config_args(parser: argparse.ArgumentParser, cls, prefix: str = "", skip: tuple[str, ...] = (), group: str | None = None) -> None:
    """Add one ``--<prefix><field>`` flag per field of dataclass ``cls`` (help = its ``#:`` doc).

    Defaults are ``None`` (= keep the dataclass default); read them back with :func:`config_from_args`.
    Tuples take comma-separated numbers; bools take true/false.
    """
    docs = field_docs(cls)
    hints = typing.get_type_hints(cls)
    g = parser.add_argument_group(group or f"{cls.__name__} options") if group is not False else parser
    for f in dataclasses.fields(cls):
        if f.name in skip or not f.init:
            continue
        flag = "--" + (prefix + f.name).replace("_", "-")
        default = f.default if f.default is not dataclasses.MISSING else (f.default_factory() if f.default_factory is not dataclasses.MISSING else None)  # type: ignore[misc]
        help_ = f"{docs.get(f.name, '')} (default {default!r})".strip()
        g.add_argument(flag, dest=f"cfg_{prefix}{f.name}", default=None, type=_parser_for(hints.get(f.name, str), flag), metavar=_metavar(hints.get(f.name, str)), help=help_.replace("%", "%%"))


def config_from_args(args: argparse.Namespace, cls, prefix: str = "", **overrides):
    """Build ``cls`` from the flags of :func:`add_config_args` (unset flags keep the defaults)."""
    kw = {}
    for f in dataclasses.fields(cls):
        v = getattr(args, f"cfg_{prefix}{f.name}", None)
        if v is not None:
            kw[f.name] = v
    kw.update({k: v for k, v in overrides.items() if v is not None})
    try:
        return cls(**kw)
    except TypeError as exc:
        raise SplatplanError(f"bad {cls.__name__} options: {exc}") from None


def _strip_optional(tp):
    if typing.get_origin(tp) in (typing.Union, getattr(__import__("types"), "UnionType", typing.Union)):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1:
            return args[0]
    return tp


def _metavar(tp) -> str:
    tp = _strip_optional(tp)
    if typing.get_origin(tp) is tuple:
        return "A,B,..."
    return {float: "FLOAT", int: "INT", bool: "BOOL"}.get(tp, "STR")


def _parser_for(tp, flag: str):
    tp = _strip_optional(tp)

    def parse(text: str):
        try:
            if typing.get_origin(tp) is tuple:
                inner = [a for a in typing.get_args(tp) if a is not Ellipsis]
                conv = inner[0] if inner else float
                return tuple(conv(x) for x in text.split(","))
            if tp is bool:
                low = text.lower()
                if low in ("1", "true", "yes", "on"):
                    return True
                if low in ("0", "false", "no", "off"):
                    return False
                raise ValueError(text)
            if tp in (int, float):
                return tp(text)
            return text
        except ValueError:
            raise argparse.ArgumentTypeError(f"{flag}: cannot read {text!r} as {_metavar(tp)}") from None

    return parse


def add_device_arg(parser: argparse.ArgumentParser) -> None:
    """The one ``--device`` flag every subcommand shares (same meaning everywhere)."""
    parser.add_argument("--device", default="auto", help="auto (CUDA when present, else CPU) | cpu | cuda | cuda:N (default auto)")
