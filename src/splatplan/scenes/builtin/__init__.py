"""Built-in scenes: analytic primitives with an exact signed distance, and splats sampled on them.

Every built-in scene is a union of solid oriented boxes (:class:`AnalyticScene`, the exact ground
truth) plus 3DGS-like splats sampled on the box surfaces with the statistics of real captures
(:func:`~.surface_splats.splats_from_boxes`):

* ``stonehenge``: normalised units, z up, ~200k splats (the paper's E1-E4 studies);
* ``tabletop``: metres, z up, a table with box walls for the Panda at the origin (~150k splats);
* ``apartment``: metres, z up, three rooms and doorways for the Go2 (~160k splats).

    from splatplan.scenes.builtin import build_builtin, write_builtin
    splats, gt = build_builtin("tabletop")
    ply, gt_json = write_builtin("apartment", "apartment.ply")
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

from ..._resources import require_bytes
from ...errors import SplatplanError
from . import apartment, stonehenge, tabletop
from .analytic_scene import AnalyticScene
from .surface_splats import SurfaceSplatConfig, splats_from_boxes, splats_from_scene

__all__ = ["BUILTIN_SCENES", "AnalyticScene", "SurfaceSplatConfig", "build_builtin", "splats_from_boxes", "splats_from_scene", "write_builtin"]


def _no_haze(name: str, haze: bool) -> None:
    if haze:
        raise SplatplanError(f"the {name} scene has no real-capture look (haze): only the apartment has one")


def _stonehenge(seed: int = 0, n_splats: int | None = None, level: int = 1, haze: bool = False):
    _no_haze("stonehenge", haze)
    return stonehenge.build_stonehenge(level=level, seed=seed, n_splats=n_splats)


def _tabletop(seed: int = 0, n_splats: int | None = None, level: int = 1, haze: bool = False):
    _no_haze("tabletop", haze)
    if level != 1:
        raise SplatplanError("the tabletop scene has one splat level (1)")
    return tabletop.build_tabletop(seed=seed, n_splats=n_splats)


def _apartment(seed: int = 0, n_splats: int | None = None, level: int = 1, haze: bool = False):
    if level != 1:
        raise SplatplanError("the apartment scene has one splat level (1)")
    return apartment.build_apartment(seed=seed, n_splats=n_splats, haze=haze)


#: name -> builder ``(seed=0, n_splats=None, level=1, haze=False) -> (Splats, AnalyticScene)``.
BUILTIN_SCENES: dict[str, Callable] = {"stonehenge": _stonehenge, "tabletop": _tabletop, "apartment": _apartment}


#: bytes per splat while a built-in scene is sampled (float64 intermediates): an estimate
SPLAT_BUILD_BYTES = 1024


def build_builtin(name: str, seed: int = 0, n_splats: int | None = None, level: int = 1, haze: bool = False):
    """Splats and exact ground truth of a built-in scene (fresh copies; cached in memory).

    Args:
        name: one of :data:`BUILTIN_SCENES`.
        seed: layout jitter and sampling seed.
        n_splats: total splat count (default: the scene's own).
        level: Gaussian-size level (stonehenge 1..5; the others 1).
        haze: the apartment's real-capture look (:func:`.apartment.add_capture_look`: haze, a
            mirror layer under a shiny floor, floor-level matter); the other scenes refuse it.

    Returns:
        (Splats, AnalyticScene).
    """
    if name not in BUILTIN_SCENES:
        raise SplatplanError(f"unknown built-in scene {name!r}: available: {', '.join(BUILTIN_SCENES)}")
    if n_splats is not None:  # the sampler holds several float64 copies of every splat
        require_bytes(float(n_splats) * SPLAT_BUILD_BYTES, f"{name} with {int(n_splats):,} splats", "the splat count (--n-splats)")
    return BUILTIN_SCENES[name](seed=int(seed), n_splats=n_splats, level=int(level), haze=bool(haze))


def write_builtin(name: str, out_ply, seed: int = 0, level: int = 1, haze: bool = False) -> tuple[Path, Path]:
    """Write a built-in scene as an INRIA 3DGS .ply plus its ground truth ``<stem>.gt.json``
    (``haze``: the apartment's real-capture look, see :func:`build_builtin`).

    Returns:
        (ply path, ground-truth JSON path).
    """
    if name == "stonehenge":
        _no_haze(name, haze)
        return stonehenge.write_stonehenge(out_ply, level=level, seed=seed)
    out_ply = Path(out_ply)
    if out_ply.suffix.lower() != ".ply":
        raise SplatplanError(f"write_builtin writes an INRIA .ply; got {out_ply.name!r} (use a .ply name)")
    splats, scene = build_builtin(name, seed=seed, level=level, haze=haze)
    out_ply.parent.mkdir(parents=True, exist_ok=True)
    stonehenge.save_ply(out_ply, splats)
    gt = stonehenge.ground_truth_path(out_ply)
    meta = {**scene.meta, "n_splats": len(splats), "n_floaters": int(splats.info["n_floaters"]), "ply": out_ply.name}
    if haze:
        meta["capture_look"] = dict(splats.info["capture_look"])
    AnalyticScene(scene.boxes, scene.labels, meta).save(gt)
    return out_ply, gt
