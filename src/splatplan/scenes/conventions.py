"""The frame a splat file lands in after loading, and the sidecar of an aligned file.

Readers keep a file's own frame (positions in the file's units; ``.spz`` is turned from its RUB
axes into the INRIA convention). What "up" is then depends on the tool that wrote the file:

* INRIA 3DGS ``.ply``, gsplat ``.pt``: the COLMAP world frame, the first camera's axes: x right,
  **y down**, z forward. Up is usually ``-y``, tilted by however the first photo was held.
* nerfstudio ``.ply`` (header ``comment Vertical Axis: z``): nerfstudio's world, **z up**.
* SuperSplat / PlayCanvas compressed ``.ply``, antimatter15 ``.splat``: the frame of the ``.ply``
  they were made from, usually INRIA (**up -y**).
* Niantic ``.spz``: stored RUB (x right, y up, z back), read as RDF: **up -y**, like INRIA.
* Files written by splatplan (``scene align``, built-in scenes: a ``.align.json`` or ``.gt.json``
  beside them): **z up**, the floor at the height their sidecar records.

:func:`capture_convention` reads these cues (the ``up_hint`` of alignment); :func:`read_align_sidecar`
reads what ``splatplan scene align`` wrote beside its output. A leaf module: no other splatplan import.
"""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["FORMAT_FRAMES", "align_sidecar_path", "capture_convention", "read_align_sidecar"]

#: one line per input kind: the frame it lands in after loading (help texts and docs quote it)
FORMAT_FRAMES = {
    "INRIA .ply / gsplat .pt": "COLMAP frame of the first camera: x right, y down, z forward (up usually -y)",
    "nerfstudio .ply": "header 'comment Vertical Axis: z': z up",
    "SuperSplat compressed .ply, .splat": "the frame of the .ply they came from, usually INRIA (up -y)",
    ".spz": "stored RUB (y up), loaded as INRIA RDF: up -y",
    "splatplan output": "z up, floor at the height in its .align.json / .gt.json sidecar",
}


def align_sidecar_path(scene_path) -> Path:
    """The transform sidecar that ``scene align`` writes beside its output: PATH.ply -> PATH.align.json."""
    return Path(scene_path).with_suffix(".align.json")


def read_align_sidecar(scene_path) -> dict | None:
    """The ``.align.json`` beside ``scene_path`` as a dict, or None when there is none (or it is not
    an alignment record: unreadable, not JSON, no ``transform``)."""
    p = align_sidecar_path(scene_path)
    try:
        doc = json.loads(p.read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    return doc if isinstance(doc, dict) and "transform" in doc else None


def _ply_vertical_axis(path: Path) -> str | None:
    """'z' when a ``.ply`` header says ``comment Vertical Axis: z`` (nerfstudio), else None. Other
    values are not trusted (some exporters write a fixed ``y`` whatever the frame)."""
    try:
        with open(path, "rb") as f:
            head = f.read(65536)
    except OSError:
        return None
    text = head.split(b"end_header", 1)[0].decode("ascii", errors="replace")
    for line in text.splitlines():
        low = line.strip().lower()
        if low.startswith("comment vertical axis:") and low.split(":", 1)[1].strip() == "z":
            return "z"
    return None


def capture_convention(path) -> tuple[str, str]:
    """(up_hint, why): the up axis a file's convention implies (see the module docstring)."""
    p = Path(path)
    if p.with_suffix(".align.json").is_file() or p.with_suffix(".gt.json").is_file():
        return "+z", "written by splatplan (a sidecar beside it)"
    if p.suffix.lower() == ".ply" and _ply_vertical_axis(p) == "z":
        return "+z", "the .ply header says 'Vertical Axis: z' (nerfstudio)"
    return "-y", "INRIA/COLMAP convention (y down)"
