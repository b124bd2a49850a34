"""Config dataclasses -> command-line flags: one ``--<prefix><field>`` flag per field, its help the
field's ``#:`` doc, its value parsed from the field's type and checked against the field's declared
range (:mod:`splatplan._config`); :func:`config_from_args` builds the config back.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import functools
import inspect
import linecache
import re
import types
import typing
from typing import Literal

from .._config import NESTED_SKIP, check_config, check_value
from .._resources import ResourceError
from ..errors import SplatplanError
from ._values import strict_float, strict_int

__all__ = ["Unset", "add_config_args", "config_from_args", "field_docs"]


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


class Unset:
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


def add_config_args(parser: argparse.ArgumentParser | argparse._ArgumentGroup, cls, prefix: str = "", skip: tuple[str, ...] = (), group: str | Literal[False] | None = None,
                    base=None) -> None:
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
        g.add_argument(flag, dest=f"cfg_{prefix}{f.name}", default=Unset, type=_parser_for(tp, flag, f, cls.__name__), metavar=_metavar(tp), help=help_.replace("%", "%%"))


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
        v = getattr(args, f"cfg_{prefix}{f.name}", Unset)
        if v is not Unset:
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
                mapping = {}
                for it in (x for x in text.split(",") if x.strip()):
                    k, sep, v = it.partition("=")
                    if not sep:
                        raise ValueError(it)
                    mapping[_scalar(kt, k.strip())] = _scalar(vt, v.strip())
                return mapping
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
