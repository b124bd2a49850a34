"""A cache of fitted link models, so a URDF is fitted once, not at every ``load_robot``.

Key: SHA-256 over the fit method and its version, the fit parameters, and per link every
collision element (kind, origin, size) with the content hash of its mesh file. Value: the
ellipsoid YAML (:func:`~splatplan.robots.fit.save_yaml`), written atomically.

Location: ``$SPLATPLAN_FIT_CACHE`` if set, else ``<repo>/build/robot-fits`` in a source checkout
(beside the Warp kernel cache), else ``~/.cache/splatplan/robot-fits``. Nothing is ever written
next to the user's URDF.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import asdict
from pathlib import Path

from .fit import EllipsoidSet, fit_model, load_yaml, save_yaml
from .fit_cover import COVER_VERSION, FitConfig
from .urdf import UrdfModel


def cache_dir() -> Path:
    env = os.environ.get("SPLATPLAN_FIT_CACHE")
    if env:
        return Path(env)
    repo = Path(__file__).resolve().parents[3]
    if (repo / "pyproject.toml").exists():
        return repo / "build" / "robot-fits"
    return Path.home() / ".cache" / "splatplan" / "robot-fits"


def _file_hash(path) -> str:
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError:
        return "missing"


def fit_key(model: UrdfModel, method: str, per_link, from_visual: bool, config: FitConfig | None) -> str:
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
        "version": COVER_VERSION if method == "cover" else 1,
        "per_link": per_link,
        "from_visual": bool(from_visual),
        "config": asdict(config or FitConfig()) if method == "cover" else None,
        "links": links,
    }
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def cached_fit(model: UrdfModel, method: str = "cover", per_link=1, from_visual: bool = False, config: FitConfig | None = None) -> tuple[EllipsoidSet, Path]:
    """The fit of ``model`` from the cache, or fitted now and stored; returns (ellipsoids, cache file)."""
    key = fit_key(model, method, per_link, from_visual, config)
    path = cache_dir() / f"{key[:32]}.yaml"
    if path.is_file():
        try:
            return load_yaml(path, model.kin.link_names), path
        except Exception:  # a damaged entry is refitted and overwritten
            pass
    ells = fit_model(model, per_link=per_link, from_visual=from_visual, method=method, config=config)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_yaml(ells, path, robot=model.name, urdf=str(model.path), note=f"fit cache: method {method}, key {key}")
    return ells, path
