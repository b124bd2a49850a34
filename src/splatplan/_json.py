"""Valid JSON from numpy-laden results: non-finite floats as null, numpy values as plain ones."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ._files import atomic_path

__all__ = ["dumps_json", "json_safe", "write_json"]


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
    """The one JSON writer of the CLI and the studies: valid JSON always (:func:`json_safe`, then ``allow_nan=False``)."""
    return json.dumps(json_safe(obj), allow_nan=False, **kw)


def write_json(path: str | Path, obj) -> None:
    """Write ``obj`` as indented JSON (:func:`dumps_json`) to ``path``, atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(dumps_json(obj, indent=2) + "\n")
