"""Command-line text -> values: numbers in the CLI's spelling, comma lists, vectors, poses.

Every parser here raises :class:`~splatplan.errors.SplatplanError` (or ``ValueError`` for the
strict number readers) with one line naming the flag and the expected form.
"""

from __future__ import annotations

import re

import numpy as np

from ..errors import SplatplanError

__all__ = ["MAX_COORD", "NUMBER_LIST", "parse_base_pose", "parse_numbers", "parse_vec3", "strict_float", "strict_int", "unit_quaternion"]

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


def parse_vec3(text: str, what: str, max_abs: float | None = MAX_COORD) -> np.ndarray:
    """'X,Y,Z' -> (3,) float64: finite, each within ``max_abs`` (a position: :data:`MAX_COORD`)."""
    return parse_numbers(text, what, "three numbers X,Y,Z", 3, max_abs)


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
