"""Plumbing shared by the study modules (pr, throughput, conservatism, linearization): atomic
output files for their ``report`` functions, the device spelling check of their configs and the
config echo of their JSON.
"""

from __future__ import annotations

import json
import re
from dataclasses import asdict
from pathlib import Path
from typing import Any

from .._files import atomic_path
from ..errors import SplatplanError

#: what a study config's ``device`` field accepts
DEVICE_DOC = "auto (CUDA when present, else CPU) | cpu | cuda | cuda:N"


def check_device(device: str, owner: str) -> None:
    """Raise SplatplanError unless ``device`` is spelled as :data:`DEVICE_DOC` says (not resolved here)."""
    if not isinstance(device, str) or not re.fullmatch(r"auto|cpu|cuda(:\d+)?", device):
        raise SplatplanError(f"{owner}.device {device!r} not understood: use {DEVICE_DOC}")


def config_dict(cfg) -> dict[str, Any]:
    """A config dataclass as the study JSON records it (tuples as lists)."""
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(cfg).items()}


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically; returns the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return Path(path)


def write_json(path: str | Path, data) -> Path:
    """Write ``data`` as indented JSON (NaN allowed, as ``json.dumps``) atomically; returns the path."""
    return write_text(path, json.dumps(data, indent=2) + "\n")


def save_figure(fig, path: str | Path, dpi: float | None = None) -> Path:
    """Save a matplotlib ``Figure`` to ``path`` atomically (format from the suffix); returns the path."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=Path(path).suffix.lstrip(".") or None, **({"dpi": dpi} if dpi else {}))
    return Path(path)
