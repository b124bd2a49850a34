"""Every config field is declared with its constraints and read somewhere (issue #21).

"Read" = the field's attribute is accessed (``x.field`` or ``getattr(x, "field")``) in a module of
``src/splatplan`` that refers to the config class by name, other than on its definition line: a
flag built from a field nobody reads (as ``--base-n-iters`` was) fails here.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import math
import pkgutil
import re
from pathlib import Path

import pytest

import splatplan
from splatplan._config import Bounds, bounded, check_config, field_bounds
from splatplan.errors import SplatplanError

SRC = Path(splatplan.__file__).parent


def config_classes() -> list[type]:
    out = []
    for m in pkgutil.walk_packages(splatplan.__path__, "splatplan."):
        if m.name.endswith("__main__"):
            continue
        mod = importlib.import_module(m.name)
        for name, c in vars(mod).items():
            if inspect.isclass(c) and dataclasses.is_dataclass(c) and c.__module__ == mod.__name__ and name.endswith("Config"):
                out.append(c)
    return out


CONFIGS = config_classes()
TEXTS = {p: p.read_text() for p in SRC.rglob("*.py")}


def test_found_the_configs():
    names = {c.__name__ for c in CONFIGS}
    assert {"MetricConfig", "RRTConfig", "MPPIConfig", "ArmConfig", "BaseConfig", "NavigateConfig", "ViewerConfig", "PRConfig"} <= names


@pytest.mark.parametrize("cls", CONFIGS, ids=lambda c: c.__name__)
def test_every_field_is_read(cls):
    users = [t for t in TEXTS.values() if re.search(rf"\b{cls.__name__}\b", t)]
    unread = []
    for f in dataclasses.fields(cls):
        # a field of a shared group (ConfigTerms: CollisionTerms, ...) may be read where the group is defined
        owner = next(k for k in reversed(cls.__mro__) if f.name in getattr(k, "__dataclass_fields__", {}))
        texts = users if owner is cls else users + [t for t in TEXTS.values() if re.search(rf"\b{owner.__name__}\b", t)]
        read = re.compile(rf"\.{f.name}\b|getattr\([^)]*[\"']{f.name}[\"']")
        definition = re.compile(rf"^\s+{f.name}\s*:")
        if not any(read.search(line) and not definition.match(line) for t in texts for line in t.splitlines()):
            unread.append(f.name)
    assert not unread, f"{cls.__name__} fields never read: {unread} (wire them or remove them)"


@pytest.mark.parametrize("cls", CONFIGS, ids=lambda c: c.__name__)
def test_defaults_and_quick_satisfy_the_constraints(cls):
    quick = [getattr(cls, m)() for m in ("quick", "quick_config") if callable(getattr(cls, m, None))]  # a study's smoke settings
    for cfg in [cls(), *quick]:
        (cfg.validate() if hasattr(cfg, "validate") and cls.__name__ != "Kinematics" else check_config(cfg))


@pytest.mark.parametrize("cls", CONFIGS, ids=lambda c: c.__name__)
def test_validate_rejects_nan_in_every_float_field(cls):
    """Every float field is finite unless it declares allow_inf; validate() names the field."""
    base = cls()
    for f in dataclasses.fields(base):
        v = getattr(base, f.name)
        if isinstance(v, float):
            with pytest.raises(SplatplanError, match=rf"{cls.__name__}\.{f.name} must be a finite number"):
                dataclasses.replace(base, **{f.name: math.nan}).validate()


def test_constraint_api():
    @dataclasses.dataclass
    class Demo:
        n: int = bounded(3, ge=1)
        rate: float = bounded(0.5, gt=0, le=1)
        mode: str = bounded("a", choices=("a", "b"))
        budget: float = bounded(1.0, gt=0, allow_inf=True)
        free: float = 2.0
        pair: tuple[float, ...] = bounded((0.1, 0.2), ge=0)

    check_config(Demo())
    check_config(Demo(budget=math.inf))
    for kw, msg in [({"n": 0}, r"Demo\.n must be >= 1, got 0"), ({"rate": 1.5}, r"Demo\.rate must be > 0 and <= 1, got 1\.5"),
                    ({"mode": "c"}, r"Demo\.mode must be one of 'a', 'b', got 'c'"), ({"free": math.inf}, r"Demo\.free must be a finite number"),
                    ({"budget": math.nan}, r"Demo\.budget must be a finite number > 0"), ({"pair": (0.1, -1.0)}, r"Demo\.pair must be >= 0, got -1\.0")]:  # fmt: skip
        with pytest.raises(SplatplanError, match=msg):
            check_config(Demo(**kw))
    assert field_bounds(dataclasses.fields(Demo)[0]) == Bounds(ge=1)


def test_cli_flag_and_library_give_the_same_message(capsys):
    from splatplan.cli import main
    from splatplan.planners import MPPIConfig
    from splatplan.tasks.arm import ArmConfig

    assert main(["mpc", "--robot", "panda", "--out", "x", "--arm-mppi-dt", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "splatplan: error: argument --arm-mppi-dt: must be > 0, got 0.0 (MPPIConfig.dt)"
    with pytest.raises(SplatplanError, match=r"^MPPIConfig\.dt must be > 0, got 0\.0$"):
        ArmConfig(mppi=MPPIConfig(dt=0.0)).validate()


def test_every_plain_flag_is_read():
    """Every non-config flag of every command is read as ``args.<dest>`` by the CLI modules."""
    import argparse

    from splatplan.cli import build_parser

    from .test_cli_fuzz import leaf_parsers

    cli_src = "\n".join(p.read_text() for p in (SRC / "cli").glob("*.py"))

    unread = []
    for path, p in leaf_parsers(build_parser()):
        for a in p._actions:
            if isinstance(a, (argparse._HelpAction, argparse._VersionAction)) or a.dest.startswith("cfg_"):
                continue  # config flags: test_every_field_is_read
            if not re.search(rf"args\.{a.dest}\b|getattr\(args, [\"']{a.dest}[\"']", cli_src):
                unread.append(f"{' '.join(path)} {a.option_strings or a.dest}")
    assert not unread, f"flags nobody reads: {unread}"


def test_config_terms_keep_range_and_doc_and_set_the_default():
    """A task config sets a shared group's defaults as class keywords; the range, the doc and the
    flat name stay the group's (planners.costs.CollisionTerms in the four task configs)."""
    from splatplan.cli._common import field_docs
    from splatplan.planners.costs import CollisionTerms, StridedCollisionTerms
    from splatplan.tasks.base import BaseConfig

    f = {g.name: g for g in dataclasses.fields(BaseConfig)}
    assert BaseConfig().n_sigma == 0.75 and CollisionTerms().n_sigma == 1.0
    assert field_bounds(f["collision_s2_cap"]) == field_bounds({g.name: g for g in dataclasses.fields(StridedCollisionTerms)}["collision_s2_cap"])
    assert field_docs(BaseConfig)["w_hit"] == field_docs(CollisionTerms)["w_hit"]
    with pytest.raises(SplatplanError, match=r"BaseConfig\.collision_s2_cap must be >= 1"):
        BaseConfig(collision_s2_cap=0.5).validate()
    with pytest.raises(TypeError, match="not a field inherited"):

        @dataclasses.dataclass
        class Bad(CollisionTerms, w_unknown=1.0):
            pass
