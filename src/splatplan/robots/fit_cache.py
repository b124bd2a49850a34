"""A cache of fitted link models, so a URDF is fitted once, not at every ``load_robot``.

Key: SHA-256 over the fit method and its version, the fit parameters, and per link every
collision element (kind, origin, size) with the content hash of its mesh file. Value: the
ellipsoid YAML (:func:`~splatplan.robots.fit.save_yaml`), written atomically.

Shipped fits (``robots/data/fits/<key>.yaml``, same key) are read first: the MotionBenchMaker
Panda's tight fit ships there, so loading it never fits.

Location: ``$SPLATPLAN_FIT_CACHE`` if set, else ``<repo>/build/robot-fits`` in a source checkout
(beside the Warp kernel cache), else ``~/.cache/splatplan/robot-fits``. Nothing is ever written
next to the user's URDF.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
from dataclasses import asdict
from pathlib import Path

from ..errors import SplatplanError
from .fit import EllipsoidSet, fit_model, load_yaml, save_yaml
from .fit_cover import COVER_VERSION, FitConfig
from .fit_opt import OPT_VERSION, OptConfig
from .urdf import UrdfModel

#: Fits shipped with the package (same keys and format as the cache): read before the cache, so
#: a URDF whose fit was made once here (the MotionBenchMaker Panda) loads without fitting.
SHIPPED = Path(__file__).parent / "data" / "fits"

#: Each fitting method's version and config class (part of the key).
_METHOD = {"cover": (COVER_VERSION, FitConfig), "opt": (OPT_VERSION, OptConfig)}


def cache_dir() -> Path:
    env = os.environ.get("SPLATPLAN_FIT_CACHE")
    if env:
        return Path(env)
    repo = Path(__file__).resolve().parents[3]
    if (repo / "pyproject.toml").exists():
        return repo / "build" / "robot-fits"
    return Path.home() / ".cache" / "splatplan" / "robot-fits"


def _file_hash(path) -> str:
    """sha256 of a mesh file: a regular file of bounded size only (``read_urdf`` refused the rest;
    this never reads a device or a FIFO, which would not end)."""
    from .._files import read_bounded
    from .urdf import MAX_MESH_BYTES

    try:
        return hashlib.sha256(read_bounded(path, "mesh", "a mesh file", MAX_MESH_BYTES)).hexdigest()
    except SplatplanError:
        if not os.path.lexists(path):
            return "missing"
        raise


def fit_key(model: UrdfModel, method: str, per_link, from_visual: bool, config=None) -> str:
    """Hex digest identifying a fit (see the module docstring)."""
    links = {}
    for link in model.kin.link_names:
        geoms = model.collisions.get(link, []) or (model.visuals.get(link, []) if from_visual else [])
        links[link] = [
            [g.kind, [round(float(v), 12) for v in g.origin.reshape(-1)], [round(float(v), 12) for v in g.size], _file_hash(g.mesh) if g.mesh else ""]
            for g in geoms
        ]
    doc = {
        "method": method,
        "version": _METHOD[method][0] if method in _METHOD else 1,
        "per_link": per_link,
        "from_visual": bool(from_visual),
        "config": asdict(config or _METHOD[method][1]()) if method in _METHOD else None,
        "links": links,
    }
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def cached_fit(model: UrdfModel, method: str = "opt", per_link=1, from_visual: bool = False, config=None) -> tuple[EllipsoidSet, Path]:
    """The fit of ``model`` shipped with the package, else from the cache, else fitted now and stored
    in the cache; returns (ellipsoids, the file read or written)."""
    from .fit import fit_work_guard

    fit_work_guard(model, per_link, from_visual)  # before a word is printed or a mesh hashed
    key = fit_key(model, method, per_link, from_visual, config)
    shipped = SHIPPED / f"{key[:32]}.yaml"
    if shipped.is_file():
        return load_yaml(shipped, model.kin.link_names), shipped
    path = cache_dir() / f"{key[:32]}.yaml"
    if path.is_file():
        try:
            return load_yaml(path, model.kin.link_names), path
        except Exception:  # a damaged entry is refitted and overwritten
            pass
    # a first fit takes minutes (about a CPU-minute per link for "opt"): say so once, on stderr
    print(f"note: fitting {model.name}'s {len(model.kin.link_names)} links with method {method!r} "
          f"(once; cached in {path.parent})", file=sys.stderr, flush=True)  # fmt: skip
    ells = fit_model(model, per_link=per_link, from_visual=from_visual, method=method, config=config)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_yaml(ells, path, robot=model.name, urdf=str(model.path), note=f"fit cache: method {method}, key {key}")
    return ells, path
