"""How well a link model (ellipsoids or spheres) fits the link's solid: one Monte Carlo procedure for any model.

Per link, against the link's collision solids (meshes / boxes; a mesh that is not watertight counts
as its convex hull, see :func:`~splatplan.robots.solids.solids_of`):

* ``coverage_surface`` / ``coverage_interior``: fraction of uniform samples on the solids' surface /
  in their interior that lie inside the model (1 = safe on those samples).
* ``volume_ratio``: union volume of the model (uniform samples in its bounding box) / the solids'
  volume, with ``volume_ratio_se``, the binomial standard error of the estimate.
* ``reach_m``: the farthest a model point lies outside the solids, max over samples on every
  ellipsoid's surface of the exact signed distance (trimesh) to the nearest solid. The maximum
  over the union is attained on its boundary, which lies on the ellipsoids' surfaces; with
  ``n_surface`` samples per ellipsoid the true value exceeds the estimate by at most the sample
  spacing (the distance is 1-Lipschitz).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..errors import SplatplanError
from .ellipsoid import mahalanobis, sphere_points, surface_of
from .solids import polytope, sample_solids, solids_of
from .urdf import UrdfModel, read_urdf


@dataclass
class LinkMeasure:
    """Fit quality of one link's model (see the module docstring)."""

    n: int  #: ellipsoids on the link
    coverage_surface: float  #: fraction of solid-surface samples inside the model
    coverage_interior: float  #: fraction of solid-interior samples inside the model
    volume_ratio: float  #: model union volume / solid volume
    volume_ratio_se: float  #: standard error of volume_ratio (Monte Carlo)
    reach_m: float  #: farthest model point outside the solid (m)
    solid_volume: float  #: m^3

    def to_dict(self) -> dict:
        return {k: (float(v) if isinstance(v, (float, np.floating)) else v) for k, v in asdict(self).items()}


def _inside_model(pts: np.ndarray, ells: list) -> np.ndarray:
    inside = np.zeros(len(pts), dtype=bool)
    for e in ells:
        inside |= mahalanobis(pts, *e) <= 1.0
    return inside


def _signed_distance(solids: list, pts: np.ndarray) -> np.ndarray:
    """(N,) distance to the union of solids, > 0 outside, <= 0 inside (exact, trimesh)."""
    import trimesh

    out = np.full(len(pts), np.inf)
    for m in solids:
        out = np.minimum(out, -trimesh.proximity.signed_distance(m, pts))  # trimesh: > 0 inside
    return out


def measure_link(ells: list, polys: list, n_samples: int = 20000, n_surface: int = 2000, seed: int = 0) -> LinkMeasure:
    """Measure a link model [(c, R, s), ...] (link frame) against its mesh/box elements (trimesh, link frame)."""
    if int(n_samples) < 1 or int(n_surface) < 1:
        raise SplatplanError(f"model measurement needs at least one sample, got n_samples={n_samples}, n_surface={n_surface}")
    rng = np.random.default_rng(seed)
    solids = solids_of(polys)
    surf, interior = sample_solids(solids, n_samples, rng)
    cov_s = float(_inside_model(surf, ells).mean())
    cov_i = float(_inside_model(interior, ells).mean()) if len(interior) else 1.0
    vol = float(sum(m.volume for m in solids))
    half = np.array([np.abs(r) @ s for _, r, s in ells])
    ctr = np.array([c for c, _, _ in ells])
    lo, hi = (ctr - half).min(axis=0), (ctr + half).max(axis=0)
    box = float(np.prod(hi - lo))
    pts = rng.uniform(lo, hi, size=(4 * n_samples, 3))
    p = float(_inside_model(pts, ells).mean())
    uv, se = p * box, box * np.sqrt(p * (1.0 - p) / len(pts))
    dirs = sphere_points(n_surface)
    on = np.concatenate([surface_of(e, dirs) for e in ells])
    # only points outside every solid's bounding box grown by the current best can matter; compute all
    reach = float(max(_signed_distance(solids, on).max(), 0.0))
    return LinkMeasure(len(ells), cov_s, cov_i, uv / vol, se / vol, reach, vol)


def measure_robot(robot, reference=None, n_samples: int = 20000, n_surface: int = 2000, seed: int = 0) -> dict[str, LinkMeasure | None]:
    """Per link of ``robot`` that has ellipsoids: its model measured against the collision meshes and
    boxes of the same-named link of ``reference`` (a URDF path or :class:`UrdfModel`; default the
    robot's own URDF). None for links whose reference has no mesh or box (spheres, cylinders and
    capsules are fitted analytically). Spheres are ellipsoids with equal semi-axes, so a sphere
    model (e.g. VAMP's spherized Panda loaded from its URDF) is measured the same way.
    """
    if reference is None:
        reference = robot.info.get("urdf")
        if not reference:
            raise SplatplanError(f"robot {robot.name}: no URDF to measure its model against (give a reference URDF)")
    ref = reference if isinstance(reference, UrdfModel) else read_urdf(reference)
    out: dict[str, LinkMeasure | None] = {}
    for li in sorted(set(robot.ellipsoid_link.tolist())):
        link = robot.link_names[li]
        sel = np.flatnonzero(robot.ellipsoid_link == li)
        ells = [(robot.ellipsoid_local[e, :3, 3], robot.ellipsoid_local[e, :3, :3], robot.semi_axes[e]) for e in sel]
        polys = [polytope(g, link) for g in ref.collisions.get(link, []) if g.kind in ("mesh", "box")]
        out[link] = measure_link(ells, polys, n_samples, n_surface, seed) if polys else None
    return out
