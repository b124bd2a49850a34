"""Plumbing shared by the study modules (pr, throughput, conservatism, linearization, and the task
studies arm, base, reach, navigate): the base of their configs (:class:`StudyConfig`: ``device``,
``quick``, ``validate``; :class:`TaskStudyConfig` for a study that runs one task's config,
:class:`ImageGoalStudyConfig` for one with image goals), the base
of the task studies' results (:class:`StudyResult`), the config echo of their JSON, and the atomic
output files of their ``report`` functions (:func:`write_outputs`).
"""

from __future__ import annotations

import json
import re
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from .._config import bounded, check_config
from ..encoders import ENCODER_NAMES
from .._files import atomic_path
from ..errors import SplatplanError

#: what a study config's ``device`` field accepts
DEVICE_DOC = "auto (CUDA when present, else CPU) | cpu | cuda | cuda:N"


def check_device(device: str, owner: str) -> None:
    """Raise SplatplanError unless ``device`` is spelled as :data:`DEVICE_DOC` says (not resolved here)."""
    if not isinstance(device, str) or not re.fullmatch(r"auto|cpu|cuda(:\d+)?", device):
        raise SplatplanError(f"{owner}.device {device!r} not understood: use {DEVICE_DOC}")


@dataclass
class StudyConfig:
    """Base of the study configs: the fields every study has, and :meth:`validate`, which checks
    every field's declared range (:mod:`splatplan._config`), the device spelling, then the study's
    cross-field rules (:meth:`check`)."""

    #: Where the metric (and the renderer / encoder of a study that has them) runs: auto (CUDA when present, else CPU) | cpu | cuda | cuda:N.
    device: str = "auto"
    #: The study's smoke-test settings (its ``quick_config()``, ``--quick``); recorded in the JSON.
    quick: bool = False

    def validate(self):
        """Raise SplatplanError naming the field when a value is not allowed; returns self."""
        check_config(self)
        check_device(self.device, type(self).__name__)
        self.check()
        return self

    def check(self) -> None:
        """The study's cross-field rules (raise SplatplanError); none by default."""


@dataclass
class TaskStudyConfig(StudyConfig):
    """Base of a study that runs a task: its subclass declares ``task`` (the task's config dataclass,
    which has a ``validate()``); :meth:`check` validates it (nothing on the bare base)."""

    def check(self) -> None:
        task = getattr(self, "task", None)
        if task is not None:
            task.validate()


@dataclass
class ImageGoalStudyConfig(TaskStudyConfig):
    """Base of a task study whose goals are images (reach, navigate): the image encoder."""

    #: image encoder (thumbnail: weight-free, not learned)
    encoder: str = bounded("thumbnail", choices=ENCODER_NAMES)
    #: encoder weights (DINOv2: a Hugging Face folder; efficientnet-lite0: an optional .pth); None = the default
    encoder_weights: str | None = None


@dataclass
class StudyResult:
    """Base of the task studies' results: ``data`` is the content of the study's JSON."""

    data: dict

    def to_json(self) -> dict:
        """The content of the study's JSON."""
        return self.data


def config_dict(cfg) -> dict[str, Any]:
    """A config dataclass as the study JSON records it (tuples as lists)."""
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(cfg).items()}


def write_text(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically; returns the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return Path(path)


def write_json(path: str | Path, data, indent: int = 2) -> Path:
    """Write ``data`` as indented JSON (NaN allowed, as ``json.dumps``) atomically; returns the path."""
    return write_text(path, json.dumps(data, indent=indent) + "\n")


def save_figure(fig, path: str | Path, dpi: float | None = None) -> Path:
    """Save a matplotlib ``Figure`` to ``path`` atomically (format from the suffix); returns the path."""
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=Path(path).suffix.lstrip(".") or None, **({"dpi": dpi} if dpi else {}))
    return Path(path)


def write_outputs(out_dir: str | Path, stem: str, data, md: str, figures=(), indent: int = 2) -> list[Path]:
    """A study's outputs in ``out_dir`` (an existing folder), each written atomically:
    ``<stem>.json`` (``data``, JSON indented by ``indent``), ``<stem>.md`` (``md``) and every
    ``(file name, Figure, dpi or None)`` of ``figures`` (any iterable: a generator draws one figure
    at a time). Returns the paths in that order."""
    out_dir = Path(out_dir)
    paths = [write_json(out_dir / f"{stem}.json", data, indent), write_text(out_dir / f"{stem}.md", md)]
    return paths + [save_figure(fig, out_dir / name, dpi=dpi) for name, fig, dpi in figures]


def note_lines(note: str | None) -> list[str]:
    """A study note as a bold markdown paragraph (no lines when there is none)."""
    return [f"**{note}**", ""] if note else []

