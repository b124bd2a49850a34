"""The CLI's parser and its plain flags: one-line usage errors, typed and range-checked values,
and the flags several commands share (``--seed``, ``--device``, ``--base-pose``, the job engine,
the metric and terrain options).

Nothing here imports a heavy library at module level.
"""

from __future__ import annotations

import argparse
import re
import sys

import numpy as np

from ..errors import SplatplanError
from ._config_flags import add_config_args, config_from_args
from ._values import NUMBER_LIST, strict_float, strict_int

__all__ = [
    "BASE_POSE_HELP", "DEVICE_HELP", "MAX_WORKERS", "PORT", "POSITIVE_INT", "SEED", "Parser", "UsageError", "add_base_pose_arg", "add_command",
    "add_device_arg", "add_engine_args", "add_metric_args", "add_seed_arg", "add_terrain_args", "allow_negative_values", "check_device",
    "engine_from_args", "float_arg", "ground_robot_scene", "int_arg", "metric_config_from_args", "reject_nan_flags",
]  # fmt: skip


BASE_POSE_HELP = ("X,Y,Z[,QW,QX,QY,QZ]: where the robot's base stands in the scene (metres, wxyz; after `scene align` the "
                  "world is z-up with the floor at z = 0): an arm's mount, or the floor frame a ground robot (go2) drives in "
                  "(its x, y, yaw are in that frame; its standing height is added); default the origin")


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


def add_command(sub, name: str, func, help: str, description: str | None = None) -> argparse.ArgumentParser:
    """A (sub)command of ``sub`` whose action is ``func(args) -> exit code``; ``help`` is its line in
    the parent's --help, ``description`` (default ``help``) heads its own."""
    s = sub.add_parser(name, help=help, description=description)
    s.set_defaults(func=func)
    return s


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
