"""Constraints on config fields: declared once, with the field, and checked in one place.

A config dataclass declares each field's valid range in the field itself::

    from dataclasses import dataclass
    from splatplan._config import bounded, check_config

    @dataclass
    class MyConfig:
        #: samples per iteration
        n_samples: int = bounded(64, ge=1)
        #: control period (s)
        dt: float = bounded(0.1, gt=0, le=10)
        #: wall-clock budget (s); inf = none
        budget_s: float = bounded(10.0, gt=0, allow_inf=True)
        #: how costs are combined
        reduce: str = bounded("mean", choices=("mean", "sum"))
        #: a field without a declared range: still must be finite (it is a float)
        w_goal: float = 1.0

        def validate(self) -> "MyConfig":
            check_config(self)  # every field's range, choice list and finiteness
            ...  # cross-field rules only (e.g. n_knots <= horizon)
            return self

Rules (one validator, :func:`check_config`, serves the library and the CLI):

- ``ge`` / ``gt`` / ``le`` / ``lt`` bound numbers; ``choices`` lists the allowed values.
- Every float (a float field, or the floats of a tuple field) must be finite unless the field says
  ``allow_inf=True`` (NaN is never accepted). This holds for fields without ``bounded`` too.
- ``None`` passes for ``X | None`` fields (it means "derived" or "off"); tuples are checked
  element by element.
- The CLI's config flags (:func:`splatplan.cli._common.add_config_args`) check the same
  constraints while parsing (``splatplan: error: argument --arm-dt: must be > 0, got 0.0``); the
  library's ``validate()`` raises :class:`~splatplan.errors.SplatplanError` with the same text,
  naming ``Class.field`` instead of the flag.

``bounded(...)`` returns a ``dataclasses.field``; for a field that needs ``default_factory`` or
other ``field()`` arguments, pass ``metadata=bounds(...)`` to ``field()`` instead.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from .errors import SplatplanError

__all__ = ["NESTED_SKIP", "Bounds", "ConfigTerms", "bounded", "bounds", "check_config", "check_value", "field_bounds"]

_KEY = "splatplan.bounds"
#: ``field(metadata={NESTED_SKIP: ("u_min", ...)})`` on a config embedded in another (e.g. a task's
#: ``MPPIConfig``): those of its fields get no CLI flag, the enclosing config sets them
NESTED_SKIP = "splatplan.nested_skip"


@dataclass(frozen=True)
class Bounds:
    """The valid values of one config field (see the module docstring)."""

    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    choices: tuple | None = None
    allow_inf: bool = False

    def describe(self) -> str:
        """The range as words: ``> 0 and <= 1``, ``one of 'a', 'b'`` (empty when only finiteness)."""
        if self.choices is not None:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        return " and ".join(f"{op} {_fmt(v)}" for op, v in ((">=", self.ge), (">", self.gt), ("<=", self.le), ("<", self.lt)) if v is not None)

    def problem(self, value) -> str | None:
        """Why ``value`` (a scalar) is not allowed, or None when it is. A side of the range that
        the field leaves open is still capped at :data:`MAX_MAGNITUDE` (no count, size, weight or
        coordinate of the library means anything beyond it; past it float32 and int64 arithmetic
        overflows)."""
        if value is None:
            return None
        if self.choices is not None:
            return None if value in self.choices else f"must be {self.describe()}, got {value!r}"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return None
        rng = self.describe()
        if isinstance(value, float) and (math.isnan(value) or (math.isinf(value) and not self.allow_inf)):
            return f"must be a finite number{' ' + rng if rng else ''}, got {value}"
        bad = (
            (self.ge is not None and not value >= self.ge)
            or (self.gt is not None and not value > self.gt)
            or (self.le is not None and not value <= self.le)
            or (self.lt is not None and not value < self.lt)
        )
        if bad:
            return f"must be {rng}, got {value}"
        hi_open = self.le is None and self.lt is None
        lo_open = self.ge is None and self.gt is None
        if not (isinstance(value, float) and math.isinf(value)) and ((hi_open and value > MAX_MAGNITUDE) or (lo_open and value < -MAX_MAGNITUDE)):
            return f"must be {rng + ' and ' if rng else ''}within +-{MAX_MAGNITUDE:g}, got {value:g}"
        return None


#: the cap of a number whose declared range leaves a side open (see :meth:`Bounds.problem`)
MAX_MAGNITUDE = 1e12


def _fmt(v) -> str:
    return str(v) if isinstance(v, int) else f"{v:g}"


#: constraints of a float field that declares nothing: finite
_FINITE = Bounds()


def bounds(*, ge=None, gt=None, le=None, lt=None, choices=None, allow_inf: bool = False) -> dict:
    """Field metadata declaring a range: ``field(default_factory=..., metadata=bounds(ge=0))``."""
    return {_KEY: Bounds(ge=ge, gt=gt, le=le, lt=lt, choices=None if choices is None else tuple(choices), allow_inf=allow_inf)}


def bounded(default, *, ge=None, gt=None, le=None, lt=None, choices=None, allow_inf: bool = False):
    """A dataclass field with a default and a declared range (see the module docstring)."""
    return dataclasses.field(default=default, metadata=bounds(ge=ge, gt=gt, le=le, lt=lt, choices=choices, allow_inf=allow_inf))


class ConfigTerms:
    """Base of a group of config fields that several configs share (a mixin dataclass, e.g. the
    collision-cost terms of every MPPI task). A config inherits the group and sets its own defaults
    as class keywords::

        @dataclass
        class ArmConfig(TaskConfig, CollisionTerms, n_sigma=1.0, w_hit=20.0): ...

    Each field keeps its declared range and its ``#:`` doc (the CLI's help); only the default
    changes, and the field names (so the CLI flags) are the group's, flat in the config."""

    def __init_subclass__(cls, **defaults) -> None:
        super().__init_subclass__()
        if not defaults:
            return
        inherited: dict[str, dataclasses.Field] = {}
        for klass in reversed(cls.__mro__[1:]):
            inherited.update(getattr(klass, "__dataclass_fields__", {}))
        own = dict(cls.__dict__.get("__annotations__", {}))
        for name, value in defaults.items():
            f = inherited.get(name)
            if f is None or name in own:
                raise TypeError(f"{cls.__name__}: {name!r} is not a field inherited from a ConfigTerms group (or it is declared again)")
            own[name] = f.type
            setattr(cls, name, dataclasses.field(default=value, metadata=f.metadata))
        cls.__annotations__ = own  # the @dataclass that follows keeps each field at its inherited place


def field_bounds(f: dataclasses.Field) -> Bounds:
    """The declared constraints of a dataclass field (finite-only when it declares none)."""
    return f.metadata.get(_KEY, _FINITE)


def check_value(f: dataclasses.Field, value) -> str | None:
    """Why ``value`` is not allowed for field ``f`` (a scalar or a tuple of scalars), or None."""
    b = field_bounds(f)
    items = value if isinstance(value, (tuple, list)) else (value,)
    for v in items:
        if isinstance(v, (tuple, list)):  # tuples of pairs: check their numbers for finiteness only
            for w in v:
                msg = _FINITE.problem(w) if isinstance(w, float) else None
                if msg:
                    return msg
            continue
        msg = b.problem(v)
        if msg:
            return msg if len(items) == 1 or not isinstance(value, (tuple, list)) else f"{msg} (in {value!r})"
    return None


def check_config(cfg, name: str | None = None):
    """Check every field of config dataclass ``cfg`` against its declared constraints.

    Returns ``cfg``. Raises :class:`SplatplanError` naming ``Class.field``, the value and the range
    on the first violation. Cross-field rules belong to the config's ``validate()``.
    """
    cls_name = name or type(cfg).__name__
    for f in dataclasses.fields(cfg):
        if not f.init:
            continue
        msg = check_value(f, getattr(cfg, f.name))
        if msg:
            raise SplatplanError(f"{cls_name}.{f.name} {msg}")
    return cfg


def check_order(cfg, low: str, high: str) -> None:
    """The cross-field rule ``cfg.<low> <= cfg.<high>``: raises :class:`SplatplanError` naming both."""
    a, b = getattr(cfg, low), getattr(cfg, high)
    if a > b:
        raise SplatplanError(f"{type(cfg).__name__}.{low} must be <= {high}, got {a} > {b}")
