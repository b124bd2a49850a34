"""Link solids and their sampling: what every link-model fitter and the measurement read.

* :func:`polytope` - a link's mesh or box collision element as a trimesh in the link frame;
  :func:`mesh_volume` its volume (the convex hull's when it is not watertight);
  :func:`check_size` - a primitive's size is finite and positive.
* :func:`solids_of` - watertight solids from those elements (a mesh that is not watertight is
  replaced by its convex hull, which contains it); :func:`inside_any` the inside test;
  :func:`sample_solids` surface and interior samples; :func:`occupancy_grid` voxels;
  :func:`simplices_of` the tetrahedra (or surface triangles) whose union is a solid, for the
  containment certificate.

A leaf of the robot stage beside :mod:`~splatplan.robots.ellipsoid` (trimesh, the ``robots`` extra,
is imported by the functions that need it).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from .urdf import Geom

__all__ = ["check_size", "inside_any", "mesh_volume", "occupancy_grid", "polytope", "sample_solids", "simplices_of", "solids_of"]

def check_size(g: Geom, link: str) -> None:
    if not np.all(np.isfinite(g.size)) or np.any(g.size <= 0):
        raise SplatplanError(f"link {link!r}: {g.kind} with invalid size {g.size.tolist()} (sizes must be finite and > 0)")


def polytope(g: Geom, link: str):
    """A trimesh in the link frame for a mesh or box element."""
    import trimesh

    if g.kind == "box":
        return trimesh.creation.box(extents=g.size, transform=g.origin)
    if g.mesh is None or not Path(g.mesh).is_file():
        where = f" (resolved to {g.mesh})" if g.ref and g.ref != str(g.mesh) else ""
        raise SplatplanError(f"link {link!r}: mesh file {g.ref or g.mesh} not found{where}")
    try:
        m = trimesh.load(str(g.mesh), force="mesh")
    except Exception as exc:
        raise SplatplanError(f"link {link!r}: mesh file {g.mesh} cannot be read ({exc.__class__.__name__}: {exc})") from None
    if not isinstance(m, trimesh.Trimesh) or len(m.vertices) == 0:
        raise SplatplanError(f"link {link!r}: mesh file {g.mesh} holds no triangles")
    v = np.asarray(m.vertices, dtype=np.float64)
    if not np.all(np.isfinite(v)):
        raise SplatplanError(f"link {link!r}: mesh file {g.mesh} has {int((~np.isfinite(v)).any(axis=1).sum()):,} vertex(es) with NaN or Inf")
    if np.any(np.abs(v) > 1e6):
        raise SplatplanError(f"link {link!r}: mesh file {g.mesh} has vertices beyond +-1e6 (largest {np.abs(v).max():.3g}); check its units")
    vs = v * np.asarray(g.size, dtype=np.float64)
    extent = np.ptp(vs, axis=0)
    if float(extent.max()) <= 1e-9:
        raise SplatplanError(f"link {link!r}: mesh file {g.mesh} has no extent (all its vertices coincide, after scale {np.asarray(g.size).tolist()})")
    sv = np.linalg.svd(vs - vs.mean(axis=0), compute_uv=False) if len(vs) >= 4 else np.zeros(3)
    if len(vs) < 4 or sv[-1] <= 1e-9 * sv[0]:  # its convex hull, which every fit measures against, has no volume
        raise SplatplanError(f"link {link!r}: mesh file {g.mesh} has no volume ({len(vs)} usable vertices, all in one plane or line; "
                             "NaN vertices are dropped when it is read)")
    m = m.copy()
    m.apply_scale(1.0)
    m.vertices = m.vertices * g.size  # per-axis URDF scale
    m.apply_transform(g.origin)
    return m


def mesh_volume(m) -> float:
    try:
        if m.is_watertight and m.volume > 0:
            return float(m.volume)
        return float(m.convex_hull.volume)
    except Exception:  # degenerate hull
        return 0.0


def solids_of(polys: list) -> list:
    """Watertight solids (trimesh) from a link's mesh/box elements: merged vertices, else the convex hull."""
    out = []
    for m in polys:
        m = m.copy()
        m.merge_vertices()
        m.remove_unreferenced_vertices()
        if not (m.is_watertight and m.volume > 0):
            m = m.convex_hull
        if m.volume < 0:
            m.invert()
        out.append(m)
    return out


def inside_any(solids: list, pts: np.ndarray) -> np.ndarray:
    """(N,) bool: the point lies in at least one solid."""
    inside = np.zeros(len(pts), dtype=bool)
    for m in solids:
        lo, hi = m.bounds
        box = np.all((pts >= lo) & (pts <= hi), axis=1)
        if box.any():
            inside[box] |= m.contains(pts[box])
    return inside


def sample_solids(solids: list, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(surface points (~n/2, 3), interior points (~n/2, 3)) spread over the solids by area / volume."""
    import trimesh

    areas = np.array([m.area for m in solids])
    vols = np.array([m.volume for m in solids])
    surf, vol = [], []
    for m, a, v in zip(solids, areas, vols):
        ns = max(8, int(round(0.5 * n * a / areas.sum())))
        pts, _ = trimesh.sample.sample_surface(m, ns, seed=int(rng.integers(2**31)))
        surf.append(np.asarray(pts))
        nv = max(8, int(round(0.5 * n * v / max(vols.sum(), 1e-300))))
        got: list[np.ndarray] = []
        tries = 0
        lo, hi = m.bounds
        while sum(len(g) for g in got) < nv and tries < 50:
            cand = rng.uniform(lo, hi, size=(4 * nv, 3))
            got.append(cand[m.contains(cand)])
            tries += 1
        vol.append(np.concatenate(got)[:nv] if got else np.zeros((0, 3)))
    return np.concatenate(surf), np.concatenate(vol)


def occupancy_grid(solids: list, pitch: float, margin: float, min_cells: int = 1):
    """Voxels of ``pitch`` over the solids' bounds plus ``margin``: (lo (3,) the grid's corner,
    shape (3,) cells per axis (>= ``min_cells``), centres (G, 3) voxel centres in C order,
    occupancy (X, Y, Z) bool: the centre lies in a solid)."""
    lo = np.min([m.bounds[0] for m in solids], axis=0) - margin
    hi = np.max([m.bounds[1] for m in solids], axis=0) + margin
    shape = np.maximum(np.ceil((hi - lo) / pitch).astype(int), int(min_cells))
    axes = [lo[i] + pitch * (np.arange(shape[i]) + 0.5) for i in range(3)]
    g = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return lo, pitch, shape, g, inside_any(solids, g).reshape(tuple(shape))


def simplices_of(solid) -> tuple[np.ndarray, bool]:
    """(K, m, 3) simplices whose union is the solid (m = 4, True) or its surface (m = 3, False)."""
    v = np.asarray(solid.vertices, dtype=np.float64)
    f = np.asarray(solid.faces)
    tri = v[f]  # (F, 3, 3)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # outward (watertight, positive volume)
    for c in (np.asarray(solid.center_mass, dtype=np.float64), v.mean(axis=0)):
        side = np.einsum("fi,fi->f", n, tri[:, 0] - c)  # > 0: c strictly inside the face's half-space
        area2 = np.linalg.norm(n, axis=1)
        ok = (side > 1e-9 * area2 * max(float(np.ptp(v, axis=0).max()), 1e-9)) | (area2 < 1e-18)
        if ok.all() and solid.contains(c[None])[0]:
            keep = area2 >= 1e-18
            return np.concatenate([np.broadcast_to(c, (int(keep.sum()), 1, 3)), tri[keep]], axis=1), True
    return tri, False
