"""Shared CLI helpers: argument parsing of vectors/robots/poses, atomic output files, config flags,
signals, devices.

Every subcommand module imports from here; nothing here imports a heavy library at module level.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import dataclasses
import functools
import inspect
import json
import linecache
import os
import re
import shutil
import signal
import sys
import tempfile
import threading
import types
import typing
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._files import atomic_path, existing_file, publish  # noqa: F401 - the commands import atomic_path from here
from .._config import NESTED_SKIP, check_config, check_value
from .._resources import ResourceError
from ..errors import SplatplanError

if TYPE_CHECKING:
    from ..robots.robot import Robot

#: a command-line token starting with a minus and a digit ("-0.3,0,0.06", "-1e-3", "-.5") or a
#: negative axis ("-y"): a value, not an option (argparse's own test accepts only a single plain
#: negative number); a malformed list such as "-0.3,x" then reaches the value parser, which names
#: the problem. No option of the CLI is spelt like this.
NUMBER_LIST = re.compile(r"^-(\.?\d\S*|[xyz])$")


#: a number as the CLI spells it: ASCII digits, an optional leading minus, a decimal point and an
#: exponent, or inf / nan (Python's float() also takes "1_0", "+3", " 3" and non-ASCII digits)
_FLOAT_TEXT = re.compile(r"-?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|-?(?:inf|infinity|nan)", re.ASCII | re.IGNORECASE)
_INT_TEXT = re.compile(r"-?\d+", re.ASCII)
#: the largest coordinate (metres or scene units) a position flag takes
MAX_COORD = 1e6


def strict_float(text: str) -> float:
    """``float(text)`` for the CLI's spelling of numbers only (see :data:`_FLOAT_TEXT`); surrounding
    blanks are allowed; ValueError otherwise."""
    t = str(text).strip()
    if not _FLOAT_TEXT.fullmatch(t):
        raise ValueError(text)
    return float(t)


def strict_int(text: str) -> int:
    """``int(text)`` for ASCII digits with an optional leading minus (no "+3", "1_0", "٣"), at most
    30 digits (a longer one is no count); ValueError otherwise."""
    t = str(text).strip()
    if not _INT_TEXT.fullmatch(t) or len(t.lstrip("-")) > 30:
        raise ValueError(text)
    return int(t)


def parse_numbers(text: str, what: str, form: str, n: int | tuple[int, ...] | None = None, max_abs: float | None = MAX_COORD) -> np.ndarray:
    """A comma list of numbers -> float64 array: ``n`` of them (an int or the allowed counts),
    finite, each within ``max_abs``; else one line naming ``what`` and the expected ``form``."""
    try:
        v = np.asarray([strict_float(x) for x in str(text).split(",")], dtype=np.float64)
    except ValueError:
        raise SplatplanError(f"{what} {text!r}: expected {form} (comma-separated numbers)") from None
    counts = (n,) if isinstance(n, int) else n
    if counts is not None and v.size not in counts:
        raise SplatplanError(f"{what} {text!r}: expected {form}, got {v.size} number(s)")
    if not np.all(np.isfinite(v)):
        raise SplatplanError(f"{what} {text!r}: values must be finite (no NaN or Inf)")
    if max_abs is not None and np.any(np.abs(v) > max_abs):
        raise SplatplanError(f"{what} {text!r}: values must be within +-{max_abs:g}")
    return v


def unit_quaternion(q: np.ndarray, what: str, text: str) -> np.ndarray:
    """``q`` (wxyz, any finite scale) normalised without overflow; a zero one is one line."""
    q = np.asarray(q, dtype=np.float64)
    m = float(np.max(np.abs(q)))
    if m == 0.0 or not np.isfinite(m):
        raise SplatplanError(f"{what} {text!r}: the quaternion QW,QX,QY,QZ is zero; use 1,0,0,0 for no rotation")
    q = q / m  # scale first: the norm of 1e300-sized parts would overflow
    n = float(np.linalg.norm(q))
    if n < 1e-9:
        raise SplatplanError(f"{what} {text!r}: the quaternion QW,QX,QY,QZ is zero; use 1,0,0,0 for no rotation")
    return q / n


def allow_negative_values(parser: argparse.ArgumentParser) -> None:
    """Let values such as ``-0.3,0,0.06`` follow an option (``--eye -0.6,0,1``), in ``parser``
    and every subparser below it (``build_parser`` applies it to the whole CLI).

    argparse classifies every token starting with '-' as an option unless it looks like a single
    negative number; this treats comma lists of numbers as values too (no option of the CLI looks
    like a number, so nothing is shadowed).
    """
    parser._negative_number_matcher = NUMBER_LIST  # noqa: SLF001 - the documented hook is missing
    for action in parser._actions:  # noqa: SLF001
        if isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
            for sub in action.choices.values():
                allow_negative_values(sub)


def reject_nan_flags(args: argparse.Namespace) -> None:
    """One place for "NaN in a flag" of the commands' own float flags (``--height``, ``--scale``,
    ``--route-time``, ...): none may be NaN; the error names the flag (one line, exit 2). Config
    fields (``cfg_*``) are left to their config's ``validate``, which names the field and its range."""
    for dest, v in vars(args).items():
        if dest.startswith("cfg_"):
            continue
        vals = v if isinstance(v, (tuple, list)) else (v,)
        if any(isinstance(x, float) and np.isnan(x) for x in vals):
            raise SplatplanError(f"--{dest.replace('_', '-')}: NaN is not a valid value")


#: the destinations of flags and positionals that name files or folders (inputs and outputs)
PATH_DESTS = frozenset({"out", "depth", "scene", "input", "poses", "configs", "images", "encoder_weights", "target_image", "urdf",
                        "spec", "tree", "plan", "mpc", "viewmat", "ellipsoids", "meshes_from", "K"})
#: the output-file flags (written through :func:`atomic_path`); ``--out`` of a command whose help
#: says "folder" is an output folder instead
OUTPUT_FILE_DESTS = frozenset({"out", "depth"})


def _path_values(v) -> list[str]:
    vals = v if isinstance(v, (list, tuple)) else [v]
    return [x for x in vals if isinstance(x, str) and x]


def check_paths(args: argparse.Namespace, parser: argparse.ArgumentParser | None = None) -> None:
    """The one cheap path check, before any work: every file or folder argument (``PATH_DESTS``)
    has components the file system can hold (a 300-character name is one line naming the flag,
    not an ``OSError`` after the planner ran), and every output file (``--out PATH.json``,
    ``--depth``) has a place to go (:func:`splatplan._files.output_target`: its folder exists, it
    is not a folder). Output folders are checked when they are made (:func:`_out_dir`)."""
    from .._files import output_target

    actions = {a.dest: a for a in (parser._actions if parser is not None else [])}  # noqa: SLF001
    helps = {d: (a.help or "") for d, a in actions.items()}
    for dest, v in vars(args).items():
        if dest not in PATH_DESTS:
            continue
        a = actions.get(dest)
        flag = a.option_strings[-1] if a is not None and a.option_strings else dest.upper()
        for text in _path_values(v):
            for part in Path(text).parts:
                n = len(os.fsencode(part))
                if n > 255:
                    raise SplatplanError(f"{flag} {text}: file name too long ({n} bytes in one name, the limit is 255)")
            if len(os.fsencode(text)) > 4095:
                raise SplatplanError(f"{flag}: path too long ({len(os.fsencode(text))} bytes, the limit is 4095)")
            if dest in OUTPUT_FILE_DESTS and "folder" not in helps.get(dest, "folder"):
                if not os.path.isdir(text):  # a folder given for a file: the command names what it expects
                    output_target(text)
            elif dest not in OUTPUT_FILE_DESTS:
                _input_not_special(flag, text)
    robot = getattr(args, "robot", None)
    if isinstance(robot, str) and robot:
        _input_not_special("--robot", robot)


def _input_not_special(flag: str, text: str) -> None:
    """An input that names a device node, a FIFO or a socket is refused before it is opened
    (reading ``/dev/zero`` never ends; a FIFO blocks until a writer comes): one line naming it."""
    import stat as _stat

    from .._files import file_kind

    try:
        st = os.stat(text)
    except (OSError, ValueError):  # missing, or a name the file system refuses: the reader says so
        return
    if not (_stat.S_ISREG(st.st_mode) or _stat.S_ISDIR(st.st_mode)):
        raise SplatplanError(f"{flag} {text} is {file_kind(st.st_mode)}, not a regular file")


def add_command(sub, name: str, func, help: str, description: str | None = None) -> argparse.ArgumentParser:
    """A (sub)command of ``sub`` whose action is ``func(args) -> exit code``; ``help`` is its line in
    the parent's --help, ``description`` (default ``help``) heads its own."""
    s = sub.add_parser(name, help=help, description=description)
    s.set_defaults(func=func)
    return s


def parse_vec3(text: str, what: str, max_abs: float | None = MAX_COORD) -> np.ndarray:
    """'X,Y,Z' -> (3,) float64: finite, each within ``max_abs`` (a position: :data:`MAX_COORD`)."""
    return parse_numbers(text, what, "three numbers X,Y,Z", 3, max_abs)


BASE_POSE_HELP = ("X,Y,Z[,QW,QX,QY,QZ]: where the robot's base stands in the scene (metres, wxyz; after `scene align` the "
                  "world is z-up with the floor at z = 0): an arm's mount, or the floor frame a ground robot (go2) drives in "
                  "(its x, y, yaw are in that frame; its standing height is added); default the origin")


def parse_base_pose(text: str | None, what: str = "--base-pose") -> np.ndarray | None:
    """'X,Y,Z' or 'X,Y,Z,QW,QX,QY,QZ' -> (4, 4) world <- base (None for None).

    Raises:
        SplatplanError: not 3 or 7 finite numbers, or a zero quaternion.
    """
    if text is None:
        return None
    v = parse_numbers(text, what, "3 numbers X,Y,Z or 7 numbers X,Y,Z,QW,QX,QY,QZ", (3, 7), None)
    if np.any(np.abs(v[:3]) > MAX_COORD):
        raise SplatplanError(f"{what} {text!r}: the position X,Y,Z must be within +-{MAX_COORD:g}")
    pose = np.eye(4)
    pose[:3, 3] = v[:3]
    if v.size == 7:
        q = unit_quaternion(v[3:], what, text)
        from ..scenes.splats import quat_to_rotmat

        pose[:3, :3] = quat_to_rotmat(q)
    return pose


def robot_at(spec: str, base_pose: np.ndarray | None, robot: Robot | None = None) -> Robot:
    """The robot named ``spec`` (or the given ``robot`` of that name, e.g. the Go2 of the tasks) with
    its base placed by ``--base-pose`` (None: unchanged). A robot that walks on terrain keeps its own
    standing offset: the pose places its floor frame, ``pose @ default base pose``."""
    from ..robots import load_robot

    robot = load_robot(spec) if robot is None else robot
    if base_pose is None:
        return robot
    if robot.walks_on_terrain:
        pose = base_pose @ robot.base_pose
        out = load_robot(spec, base_pose=pose)
        out.info.update({k: v for k, v in robot.info.items() if k not in out.info})
        out.info["standing_height_m"] = float(pose[2, 3])
        return out
    return load_robot(spec, base_pose=base_pose)


def load_npy(path: str, what: str) -> np.ndarray:
    """A real numeric ``.npy`` array as float64, or a one-line error naming ``what`` and the problem."""
    p = existing_file(path, what, "a .npy file")
    try:
        arr = np.load(p, allow_pickle=False)
    except Exception as exc:  # numpy raises several types for broken files
        raise SplatplanError(f"{what} {path} is not a readable .npy array ({exc.__class__.__name__}: {exc})") from None
    if isinstance(arr, np.lib.npyio.NpzFile):
        names = ", ".join(arr.files) or "none"
        arr.close()
        raise SplatplanError(f"{what} {path} is an .npz archive (arrays: {names}); save the one array with np.save(PATH.npy, array)")
    if not np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.complexfloating):
        raise SplatplanError(f"{what} {path}: expected a real numeric array, got dtype {arr.dtype}")
    return arr.astype(np.float64)


def load_poses(path: str) -> tuple[np.ndarray, np.ndarray | None]:
    """POSES.npy of shape (B, 3) centres or (B, 7) centre + wxyz quaternion."""
    arr = load_npy(path, "poses file")
    if arr.ndim != 2 or arr.shape[1] not in (3, 7):
        raise SplatplanError(f"poses file {path}: expected shape (B, 3) centres or (B, 7) centre + wxyz quaternion, got {arr.shape}")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise SplatplanError(f"poses file {path}: {int(bad.sum())} row(s) contain NaN or Inf (first: row {int(np.argmax(bad))})")
    if arr.shape[1] == 7:
        q = arr[:, 3:]
        if np.any(np.linalg.norm(q, axis=1) < 1e-8):
            raise SplatplanError(f"poses file {path}: zero quaternion in row {int(np.argmax(np.linalg.norm(q, axis=1) < 1e-8))}")
        return arr[:, :3], q
    return arr, None


# ---------------------------------------------------------------------------- output files
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


def json_safe(obj):
    """``obj`` with every non-finite float as None (JSON has no NaN or Infinity: Python's
    ``json.dumps`` would write bare ``NaN`` / ``Infinity``, which JSON readers refuse); numpy
    scalars and arrays as plain numbers and lists."""
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def dumps_json(obj, **kw) -> str:
    """The CLI's one JSON writer: valid JSON always (:func:`json_safe`, then ``allow_nan=False``)."""
    return json.dumps(json_safe(obj), allow_nan=False, **kw)


def write_json(path: str | Path, obj) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(dumps_json(obj, indent=2) + "\n")


#: Output folders this process created (deepest last); a command that fails removes the empty ones.
CREATED_DIRS: list[Path] = []


def _out_dir(path: str) -> Path:
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


def remove_new_outputs(keep: list[Path] = ()) -> None:
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


def _load(path: str, filter_floaters: bool = True, usable: bool = True):
    """The scene file ``path``; ``usable``: refuse (one line) splats whose values the metric and the
    renderer cannot compute with (:func:`splatplan.scenes.sanity.unusable_splats`); ``info`` passes
    False and warns instead."""
    from ..scenes.load import load_scene
    from ..scenes.sanity import unusable_splats

    scene = load_scene(path, filter_floaters=filter_floaters)
    problem = unusable_splats(scene) if usable else None
    if problem:
        raise SplatplanError(f"scene {path}: {problem}")
    return scene


def add_metric_args(parser: argparse.ArgumentParser) -> None:
    """The metric's flags (:class:`~splatplan.metric.MetricConfig`) plus ``--paper-metric``."""
    from ..metric import MetricConfig

    add_config_args(parser, MetricConfig, group="metric options (MetricConfig)")
    parser.add_argument("--paper-metric", action="store_true", help="the paper's exact metric settings (every splat counts and is inflated by "
                        "n_sigma * sigma whatever its opacity, linearised in s2: --opacity-min 0 --opacity-scaled-inflation false --linearize squared); explicit metric flags still win")


def metric_config_from_args(args: argparse.Namespace):
    """The :class:`~splatplan.metric.MetricConfig` of :func:`add_metric_args`'s flags (validated)."""
    from ..metric import MetricConfig

    return config_from_args(args, MetricConfig, base=MetricConfig.paper() if getattr(args, "paper_metric", False) else None).validate()


def add_terrain_args(parser: argparse.ArgumentParser) -> None:
    """The ground robots' terrain flags (``--terrain-floor-z``, ``--terrain-step-height``, ...)."""
    from ..scenes.terrain import TerrainConfig

    add_config_args(parser, TerrainConfig, prefix="terrain_", group="ground robots (go2): terrain (TerrainConfig; see scenes/terrain.py)")


def ground_robot_scene(scene, args, n_sigma: float):
    """The collision scene of a ground robot: ``scene`` without its terrain (the floor's splats up
    to the step height above the aligned floor), built once; prints what was removed."""
    from ..scenes.terrain import TerrainConfig, remove_terrain

    cfg = config_from_args(args, TerrainConfig, prefix="terrain_")
    out, rep = remove_terrain(scene, cfg, n_sigma=n_sigma)
    print(f"note: {rep.summary()}", file=sys.stderr)
    return out


# ---------------------------------------------------------------------------- signals
class Terminated(SystemExit):
    """Raised by the CLI's SIGTERM handler (exit code 143), so ``finally`` blocks clean up."""


def _raise_terminated(signum, frame):
    raise Terminated(128 + signum)


@contextmanager
def cli_signal_handlers():
    """SIGINT -> KeyboardInterrupt and SIGTERM -> :class:`Terminated` while the block runs (main
    thread only), so every ``finally`` (temp files of :func:`atomic_path`) runs on Ctrl-C or kill.
    A signal the caller ignores (SIG_IGN, e.g. ``nohup``-style launchers) stays ignored."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    if old[signal.SIGINT] is not signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if old[signal.SIGTERM] is not signal.SIG_IGN:
        signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)


@contextmanager
def signals_deferred():
    """Hold SIGINT/SIGTERM while native work (a Warp launch on worker threads) is in flight and
    deliver them when the block ends, as KeyboardInterrupt / :class:`Terminated`.

    Interrupting the main thread while worker threads still run a kernel lets the interpreter shut
    down under them (a segfault); use this around one bounded chunk of work at a time.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}

    def record(signum, frame):
        pending.append(signum)

    for s, h in old.items():
        if h is not signal.SIG_IGN:  # an ignored signal stays ignored
            signal.signal(s, record)
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)
    if pending:
        if signal.SIGTERM in pending:
            raise Terminated(128 + signal.SIGTERM)
        raise KeyboardInterrupt


# ---------------------------------------------------------------------------- plots
def headless_matplotlib() -> None:
    """The CLI only writes image files: matplotlib's Agg backend for this process and the worker
    processes it starts, chosen once at start-up. The library never picks a backend (its plotting
    returns Figures or saves through whatever backend its caller chose)."""
    os.environ["MPLBACKEND"] = "Agg"  # read when matplotlib is imported: costs nothing when no command plots
    mpl = sys.modules.get("matplotlib")
    if mpl is not None:  # imported already (e.g. main() called in-process): switch it now
        mpl.use("Agg")


# ---------------------------------------------------------------------------- devices
DEVICE_HELP = "auto (CUDA when present, else CPU) | cpu | cuda | cuda:N (default auto)"


def add_device_arg(parser: argparse.ArgumentParser) -> None:
    """The one ``--device`` flag every subcommand shares (same meaning everywhere)."""
    parser.add_argument("--device", default="auto", help=DEVICE_HELP)


def check_device(device: str) -> str:
    """Validate a ``--device`` value and resolve it (``auto`` -> ``cuda:0`` or ``cpu``).

    Raises:
        SplatplanError: unknown spelling, or a CUDA device that this machine does not have.
    """
    if not re.fullmatch(r"auto|cpu|cuda(:\d+)?", device or ""):
        raise SplatplanError(f"--device {device!r} not understood: use {DEVICE_HELP}")
    from .._warp import resolve_device

    return resolve_device(device)


# ---------------------------------------------------------------------------- job engine
#: the most local worker processes ``--workers`` starts
MAX_WORKERS = 256


def add_engine_args(parser: argparse.ArgumentParser) -> None:
    """``--workers N`` (a local Dask cluster on loopback) and ``--scheduler ADDR`` (an existing one);
    neither: serial, as before. Read back with :func:`engine_from_args`."""
    g = parser.add_argument_group("job engine (default: serial in this process)")
    g.add_argument("--workers", type=int_arg(le=MAX_WORKERS), default=None, metavar="N", help="run the tasks on a local Dask cluster of N worker processes (127.0.0.1 only); needs the 'distributed' extra")
    g.add_argument("--scheduler", default=None, metavar="ADDR", help="run the tasks on an existing Dask cluster, e.g. tcp://10.0.0.5:8786 (workers must have splatplan installed and the scene files at the same paths)")


def engine_from_args(args: argparse.Namespace):
    """The :class:`~splatplan.eval.engine.EngineConfig` of ``--workers`` / ``--scheduler`` (validated)."""
    from ..eval.engine import engine_from_flags

    return engine_from_flags(getattr(args, "workers", None), getattr(args, "scheduler", None))


# ---------------------------------------------------------------------------- plain flags: typed, range-checked values
class UsageError(SystemExit):
    """A command line the parser rejects (exit 2); :func:`splatplan.cli.main` returns its code."""


class Parser(argparse.ArgumentParser):
    """The CLI's ArgumentParser (its subparsers inherit it): a usage error is ONE line,
    ``splatplan: error: MESSAGE`` on stderr, exit 2 (no usage block: ``--help`` shows it)."""

    def error(self, message: str):  # noqa: D102 - argparse's hook
        print(f"splatplan: error: {' '.join(message.split())}", file=sys.stderr)
        raise UsageError(2)


def _ranged_type(convert, noun: str, bounds, name: str):
    """An argparse ``type=`` callable: ``convert(text)``, then the range check of ``bounds``."""

    def parse(text: str):
        try:
            v = convert(text)
        except (ValueError, OverflowError):
            rng = bounds.describe()
            raise argparse.ArgumentTypeError(f"expected {noun}{' ' + rng if rng else ''}, got {text!r}") from None
        msg = bounds.problem(v)
        if msg:
            raise argparse.ArgumentTypeError(msg)
        return v

    parse.__name__ = name  # argparse names the type in its own messages
    return parse


def int_arg(*, ge: int | None = None, le: int | None = None):
    """argparse ``type=`` for an integer flag with a range: ``type=int_arg(ge=0)``."""
    from .._config import Bounds

    return _ranged_type(strict_int, "an integer", Bounds(ge=ge, le=le), "int")


def float_arg(*, ge: float | None = None, gt: float | None = None, le: float | None = None, lt: float | None = None, allow_inf: bool = False):
    """argparse ``type=`` for a float flag: finite (unless ``allow_inf``) and within the range."""
    from .._config import Bounds

    return _ranged_type(strict_float, "a number", Bounds(ge=ge, gt=gt, le=le, lt=lt, allow_inf=allow_inf), "float")


#: ``--seed``: a non-negative integer that every seeded generator accepts (numpy legacy seeds stop at 2**32 - 1)
SEED = int_arg(ge=0, le=2**32 - 1)
#: a count of at least one (batch sizes, goals, ...)
POSITIVE_INT = int_arg(ge=1)
#: a TCP port
PORT = int_arg(ge=1, le=65535)


def add_seed_arg(parser: argparse.ArgumentParser, help: str = "random seed (integer >= 0; default 0)") -> None:
    """The ``--seed`` flag (a non-negative integer, checked while parsing)."""
    parser.add_argument("--seed", type=SEED, default=0, help=help)


def add_base_pose_arg(parser: argparse.ArgumentParser, help: str = BASE_POSE_HELP) -> None:
    """The ``--base-pose`` flag (text, default None; read with :func:`parse_base_pose`)."""
    parser.add_argument("--base-pose", default=None, help=help)


# ---------------------------------------------------------------------------- config dataclasses -> flags
@functools.lru_cache(maxsize=None)
def _class_spans(filename: str) -> tuple[list[str], dict[str, tuple[int, int]]]:
    """A source file's lines and the (first, last) line of every class in it, by qualified name:
    parsed once per file (``inspect.getsource`` parses the whole module again for every class)."""
    lines = linecache.getlines(filename)
    spans: dict[str, tuple[int, int]] = {}

    def visit(node, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.ClassDef):
                name = prefix + child.name
                spans[name] = (child.lineno, child.end_lineno or child.lineno)
                visit(child, name + ".")
            elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                visit(child, prefix + child.name + ".<locals>.")

    visit(ast.parse("".join(lines)), "")
    return lines, spans


def _class_source(klass) -> list[str]:
    """The source lines of a class (empty when it has none, e.g. made at run time)."""
    try:
        filename = inspect.getsourcefile(klass)
    except TypeError:
        return []
    if not filename:
        return []
    lines, spans = _class_spans(filename)
    first, last = spans.get(klass.__qualname__, (0, -1))
    return [line.rstrip("\n") for line in lines[first - 1 : last]]


def field_docs(cls) -> dict[str, str]:
    """The ``#:`` comment above each field of a dataclass (joined when it spans several lines)."""
    docs: dict[str, str] = {}
    for klass in reversed(getattr(cls, "__mro__", (cls,))):
        if not dataclasses.is_dataclass(klass):
            continue
        lines = _class_source(klass)
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


class _Unset:
    """Flag not given on the command line (keep the config's value)."""


#: A flag's explicit ``none`` (for ``X | None`` fields), distinct from "not given".
_EXPLICIT_NONE = type("_ExplicitNone", (), {"__repr__": lambda self: "None"})()


def _field_default(f: dataclasses.Field):
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
        return f.default_factory()  # type: ignore[misc]
    return None


def _show(v) -> str:
    """A default value as it would be typed on the command line."""
    if isinstance(v, dict):
        return ",".join(f"{k}={_show(x)}" for k, x in v.items()) or "''"
    if isinstance(v, (tuple, list)):
        return ",".join(":".join(_show(y) for y in x) if isinstance(x, (tuple, list)) else _show(x) for x in v) or "''"
    if v is None:
        return "none"
    if isinstance(v, bool):
        return "true" if v else "false"
    return str(v)


def add_config_args(parser: argparse.ArgumentParser, cls, prefix: str = "", skip: tuple[str, ...] = (), group: str | None = None, base=None) -> None:
    """Add one ``--<prefix><field>`` flag per field of dataclass ``cls`` (help = its ``#:`` doc).

    A field that is itself a config dataclass (e.g. a task's ``mppi: MPPIConfig``) is flattened:
    ``--<prefix><field>-<subfield>`` per subfield, except those its ``NESTED_SKIP`` metadata
    (:mod:`splatplan._config`) or ``skip`` (as ``"field.subfield"``) names.

    Defaults are "unset" (= keep the config's value); read them back with :func:`config_from_args`.
    Value syntax: numbers and strings as usual; bools true/false; ``X | None`` fields also take
    ``none``; tuples take comma-separated items (``0,1,2``), tuples of pairs ``a:1,b:2``, dicts
    ``a=1,b=2``; ``Literal`` fields list their choices. ``base`` (an instance) sets the defaults
    shown in the help. A value outside the field's declared range (``bounded(...)``, see
    :mod:`splatplan._config`) is a usage error while parsing, with the validator's message.
    """
    docs = field_docs(cls)
    hints = typing.get_type_hints(cls)
    g = parser.add_argument_group(group or f"{cls.__name__} options") if group is not False else parser
    for f in dataclasses.fields(cls):
        if f.name in skip or not f.init:
            continue
        tp = hints.get(f.name, str)
        default = getattr(base, f.name) if base is not None else _field_default(f)
        if _nested(tp):  # an embedded config: its fields flattened as --<prefix><field>-<subfield>
            inner_skip = tuple(f.metadata.get(NESTED_SKIP, ())) + tuple(n.split(".", 1)[1] for n in skip if n.startswith(f.name + "."))
            add_config_args(g, tp, prefix=f"{prefix}{f.name}_", skip=inner_skip, group=False, base=default)
            continue
        flag = "--" + (prefix + f.name).replace("_", "-")
        doc = docs.get(f.name, "")
        help_ = f"{doc} (default {_show(default)})".strip()
        g.add_argument(flag, dest=f"cfg_{prefix}{f.name}", default=_Unset, type=_parser_for(tp, flag, f, cls.__name__), metavar=_metavar(tp), help=help_.replace("%", "%%"))


def config_from_args(args: argparse.Namespace, cls, prefix: str = "", base=None, **overrides):
    """Build ``cls`` from the flags of :func:`add_config_args`.

    Unset flags keep ``base``'s value (an instance of ``cls``) or the dataclass default.
    ``overrides`` that are not None win over both.
    """
    kw = {}
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp = hints.get(f.name, str)
        if f.init and _nested(tp):
            inner = getattr(base, f.name) if base is not None else _field_default(f)
            kw[f.name] = config_from_args(args, tp, prefix=f"{prefix}{f.name}_", base=inner)
            continue
        v = getattr(args, f"cfg_{prefix}{f.name}", _Unset)
        if v is not _Unset:
            kw[f.name] = None if v is _EXPLICIT_NONE else v
    kw.update({k: v for k, v in overrides.items() if v is not None})
    try:
        cfg = dataclasses.replace(base, **kw) if base is not None else cls(**kw)
    except TypeError as exc:
        raise SplatplanError(f"bad {cls.__name__} options: {exc}") from None
    # the flags were checked while parsing; this covers the overrides, the base and cross-field rules
    validate = getattr(cfg, "validate", None)
    try:
        if callable(validate):
            validate()
        else:
            check_config(cfg)
    except ResourceError as exc:  # name the flags to lower, not the config fields
        flags = ["--" + (prefix + f.replace(".", "_")).replace("_", "-") for f in exc.fields if hasattr(args, f"cfg_{prefix}{f.replace('.', '_')}")]
        if not flags:
            raise
        head = str(exc).rsplit("; lower ", 1)[0]
        raise ResourceError(f"{head}; lower {', '.join(flags[:-1]) + ' or ' + flags[-1] if len(flags) > 1 else flags[0]}") from None
    return cfg


def _nested(tp) -> bool:
    """Whether a field's type is an embedded config dataclass (flattened into prefixed flags)."""
    return isinstance(tp, type) and dataclasses.is_dataclass(tp)


def _is_union(tp) -> bool:
    return typing.get_origin(tp) in (typing.Union, types.UnionType)


def _strip_optional(tp):
    """(inner type, whether None is allowed)."""
    if _is_union(tp):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        optional = len(args) < len(typing.get_args(tp))
        if len(args) == 1:
            return args[0], optional
        return typing.Union[tuple(args)], optional  # type: ignore[return-value]
    return tp, False


def _metavar(tp) -> str:
    tp, optional = _strip_optional(tp)
    origin = typing.get_origin(tp)
    if origin is typing.Literal:
        mv = "{" + ",".join(str(a) for a in typing.get_args(tp)) + "}"
    elif origin is tuple:
        inner = [a for a in typing.get_args(tp) if a is not Ellipsis]
        mv = "NAME:N,..." if inner and typing.get_origin(inner[0]) is tuple else "A,B,..."
    elif origin is dict:
        mv = "KEY=V,..."
    elif _is_union(tp) and any(typing.get_origin(a) is tuple for a in typing.get_args(tp)):
        mv = "X|A,B,..."
    else:
        mv = {float: "FLOAT", int: "INT", bool: "BOOL"}.get(tp, "STR")
    return f"{mv}|none" if optional else mv


def _scalar(tp, text: str):
    """Parse one scalar of type ``tp`` (int, float, bool, str, Literal, or a union of them)."""
    tp, optional = _strip_optional(tp)
    if optional and text.lower() == "none":
        return None
    if typing.get_origin(tp) is typing.Literal:
        for a in typing.get_args(tp):
            if str(a) == text:
                return a
        raise ValueError(text)
    if _is_union(tp):
        for a in typing.get_args(tp):
            try:
                return _scalar(a, text)
            except ValueError:
                pass
        raise ValueError(text)
    if tp is bool:
        low = text.lower()
        if low in ("1", "true", "yes", "on"):
            return True
        if low in ("0", "false", "no", "off"):
            return False
        raise ValueError(text)
    if tp is int:
        return strict_int(text)
    if tp is float:
        return strict_float(text)
    return text


def _parser_for(tp, flag: str, f: dataclasses.Field | None = None, owner: str = ""):
    """argparse ``type=`` callable of a config field: parse ``tp`` from text, then check the
    field's declared constraints (:mod:`splatplan._config`) so a bad value is a usage error."""
    inner, optional = _strip_optional(tp)
    origin = typing.get_origin(inner)

    def parse(text: str):
        value = _parse(text)
        if f is not None and value is not _EXPLICIT_NONE:
            msg = check_value(f, value)
            if msg:  # the library's message, plus the field it sets
                raise argparse.ArgumentTypeError(f"{msg} ({owner}.{f.name})" if owner else msg)
        return value

    def _parse(text: str):
        try:
            if optional and text.lower() == "none":
                return _EXPLICIT_NONE
            if origin is tuple:
                items = [x for x in text.split(",") if x.strip()] if text.strip() else []
                args = [a for a in typing.get_args(inner) if a is not Ellipsis]
                el = args[0] if args else float
                if typing.get_origin(el) is tuple:  # pairs "a:1,b:2"
                    sub = typing.get_args(el)
                    out = []
                    for it in items:
                        parts = it.split(":")
                        if len(parts) != len(sub):
                            raise ValueError(it)
                        out.append(tuple(_scalar(t, p) for t, p in zip(sub, parts)))
                    return tuple(out)
                if Ellipsis not in typing.get_args(inner) and len(args) > 1:  # fixed-length tuple
                    if len(items) != len(args):
                        raise ValueError(text)
                    return tuple(_scalar(t, x) for t, x in zip(args, items))
                return tuple(_scalar(el, x) for x in items)
            if origin is dict:
                kt, vt = typing.get_args(inner) or (str, str)
                out = {}
                for it in (x for x in text.split(",") if x.strip()):
                    k, sep, v = it.partition("=")
                    if not sep:
                        raise ValueError(it)
                    out[_scalar(kt, k.strip())] = _scalar(vt, v.strip())
                return out
            tuples = [a for a in typing.get_args(inner) if typing.get_origin(a) is tuple] if _is_union(inner) else []
            if tuples:  # e.g. float | tuple[float, ...]: one value or a comma list of the tuple's items
                el = [t for t in typing.get_args(tuples[0]) if t is not Ellipsis][0]
                items = [_scalar(el, x) for x in text.split(",") if x.strip()]
                if not items:
                    raise ValueError(text)
                return tuple(items) if "," in text else items[0]
            return _scalar(inner, text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"cannot read {text!r} as {_metavar(tp)}") from None

    return parse
