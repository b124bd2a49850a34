"""Named points on a scene's surfaces, so that a goal can be given without Python (``splatplan pick``).

Everything here is in the scene's own frame and units: z up with the floor at z = 0 after
``splatplan scene align`` (metres for a metric capture). Only the **opaque** splat means count
(opacity >= :attr:`PickConfig.opacity_min`): a point here is where splat centres lie, and the
surface the metric sees lies about n_sigma splat standard deviations in front of it.

What is found, on an x, y grid of :attr:`PickConfig.cell` (default: 1/200 of the scene's larger
horizontal extent):

* **Horizontal surfaces** (:class:`Surface`): the grid's height map (the highest opaque mean in each
  cell) split into connected pieces whose neighbouring cells differ by at most half a cell in
  height; a surface is what is left of a piece when only the squares of ``min_width_cells`` cells
  on a side that fit on it are kept (a wall's top, narrower, goes), above the floor's step band.
  The highest is "the top of the highest object"; its point is the cell deepest inside it
  (farthest from its edge), at the median height of its cells.
* **Walls** (:class:`Wall`): vertical surfaces. Cells whose opaque means occupy at least
  ``wall_min_height`` of height are tall; straight runs of tall cells (RANSAC lines in x, y, split
  where they break by more than two cells, both faces of a wall up to four cells thick taken as
  one) at least ``wall_min_length`` long are walls. A wall's normal is horizontal and faces the
  reference point (``near``, else the centre of the opaque means); its point is the one on the face
  toward the reference nearest to it. The largest ``n_walls`` are reported, and the nearest too.
* **Free floor** (:class:`FreeFloor`, only where a floor was found:
  :func:`~splatplan.scenes.terrain.floor_coverage`): cells holding floor splats (within
  ``step_height`` of the floor; holes up to two cells wide closed) and no opaque mean between ``floor + step_height`` and
  ``floor + height``, shrunk by a footprint radius (a robot's centre there clears every blocked
  cell at any heading). The guarantee is on the means: the planner's metric adds the splats' own
  extent.
* **The nearest surface point** to a given point (:class:`NearPoint`): the nearest opaque mean, with
  the normal of its 16 neighbours' plane (facing the point).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._config import bounded, check_config
from ..errors import SplatplanError
from .splats import Splats
from .terrain import TerrainConfig, fitted_floor_z, floor_coverage

__all__ = ["FloorInfo", "FreeFloor", "NearPoint", "PickConfig", "Picks", "Surface", "Wall", "pick_points"]


@dataclass
class PickConfig:
    """How :func:`pick_points` reads a scene (lengths in scene units: metres after ``scene align``)."""

    #: splats at least this opaque (activated opacity) are surface; fainter ones are ignored
    opacity_min: float = bounded(0.5, ge=0, le=1)
    #: floor height (world z); none = fitted from the scene (the terrain module's floor)
    floor_z: float | None = None
    #: side of the x, y grid cells; none = 1/200 of the opaque means' larger x, y extent
    cell: float | None = bounded(None, gt=0)
    #: the floor's step band: floor splats lie within this of the floor, and obstacles start above it
    step_height: float = bounded(0.05, ge=0)
    #: free floor: the clearance height above the floor that must hold no opaque mean (a robot's
    #: own height replaces it when a robot is given)
    height: float = bounded(0.5, gt=0)
    #: a horizontal surface is the union of squares of this many cells on a side that fit on it
    #: (a wall's top, narrower, is no surface)
    min_width_cells: int = bounded(5, ge=1, le=100)
    #: a cell is part of a wall when its opaque means span at least this height
    wall_min_height: float = bounded(0.15, gt=0)
    #: a wall is a straight run of wall cells at least this long
    wall_min_length: float = bounded(0.3, gt=0)
    #: how many horizontal surfaces to report (highest first)
    n_surfaces: int = bounded(5, ge=1, le=100)
    #: how many walls to report (largest first)
    n_walls: int = bounded(4, ge=0, le=100)
    #: how many free-floor regions to report (largest first)
    n_regions: int = bounded(3, ge=1, le=100)
    #: the seed of the wall search's random line hypotheses
    seed: int = bounded(0, ge=0)

    def validate(self) -> "PickConfig":
        check_config(self)
        if self.floor_z is not None and not np.isfinite(self.floor_z):
            raise SplatplanError(f"pick floor_z must be finite, got {self.floor_z}")
        return self


@dataclass
class FloorInfo:
    """The scene's floor: its height, how much of the footprint its splats cover, and whether that is a floor."""

    z: float  #: floor height (world z)
    coverage: float  #: fraction of the scene's x, y footprint with splats at floor height
    found: bool  #: coverage >= TerrainConfig.min_floor_coverage (an object capture has none)


@dataclass
class Surface:
    """A horizontal surface: ``point`` (3,) on it (the cell deepest inside it), its ``area``,
    and its x, y bounds ``lo``, ``hi`` (2,)."""

    point: np.ndarray
    area: float
    lo: np.ndarray
    hi: np.ndarray


@dataclass
class Wall:
    """A vertical surface: ``point`` (3,) on its face toward the reference, ``normal`` (3,) facing the
    reference, its ``ends`` (2, 2) in x, y, its height range ``z`` (lo, hi), ``length``, ``area``
    and ``distance`` (from the reference to ``point``)."""

    point: np.ndarray
    normal: np.ndarray
    ends: np.ndarray
    z: tuple[float, float]
    length: float
    area: float
    distance: float


@dataclass
class FreeFloor:
    """Free floor cells for a robot of ``height`` and footprint ``radius``.

    Attributes:
        cells: (K, 2) x, y centres of the cells where the robot's centre fits (floor at ``z``).
        regions: the largest connected regions of them, each ``(point (3,), area, clearance)``: the
            cell farthest from a blocked or unknown cell, and that distance.
    """

    z: float
    cell: float
    height: float
    radius: float
    cells: np.ndarray
    regions: list[tuple[np.ndarray, float, float]]

    @property
    def area(self) -> float:
        return float(len(self.cells) * self.cell**2)


@dataclass
class NearPoint:
    """The opaque splat mean nearest to ``query`` (3,): ``point`` (3,), ``normal`` (3,) facing the query, ``distance``."""

    query: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    distance: float


@dataclass
class Picks:
    """What :func:`pick_points` found (see the module docstring)."""

    n_splats: int
    n_opaque: int
    config: PickConfig
    cell: float
    floor: FloorInfo
    reference: np.ndarray  #: (3,) the point walls face and are measured from
    surfaces: list[Surface] = field(default_factory=list)
    walls: list[Wall] = field(default_factory=list)
    free: FreeFloor | None = None
    near: NearPoint | None = None

    @property
    def top(self) -> Surface | None:
        """The highest horizontal surface above the floor (None when there is none)."""
        return self.surfaces[0] if self.surfaces else None

    def to_json(self) -> dict[str, Any]:
        def r(v) -> Any:
            return np.round(np.asarray(v, dtype=np.float64), 4).tolist()

        free = None
        if self.free is not None:
            f = self.free
            free = {"z": round(f.z, 4), "cell": round(f.cell, 4), "height": round(f.height, 4), "radius": round(f.radius, 4), "area": round(f.area, 4),
                    "regions": [{"point": r(p), "area": round(a, 4), "clearance": round(c, 4)} for p, a, c in f.regions], "cells": r(f.cells)}  # fmt: skip
        return {
            "frame": "the scene's: z up, floor at z = 0 after `scene align`; scene units (metres after align)",
            "n_splats": self.n_splats,
            "n_opaque": self.n_opaque,
            "opacity_min": self.config.opacity_min,
            "cell": round(self.cell, 4),
            "floor": {"z": round(self.floor.z, 4), "coverage": round(self.floor.coverage, 4), "found": self.floor.found},
            "reference": r(self.reference),
            "top": None if self.top is None else {"point": r(self.top.point), "area": round(self.top.area, 4)},
            "surfaces": [{"point": r(s.point), "area": round(s.area, 4), "lo": r(s.lo), "hi": r(s.hi)} for s in self.surfaces],
            "walls": [{"point": r(w.point), "normal": r(w.normal), "ends": r(w.ends), "z": r(w.z), "length": round(w.length, 4), "area": round(w.area, 4),
                       "distance": round(w.distance, 4)} for w in self.walls],  # fmt: skip
            "free_floor": free,
            "near": None if self.near is None else {"query": r(self.near.query), "point": r(self.near.point), "normal": r(self.near.normal),
                                                    "distance": round(self.near.distance, 4)},  # fmt: skip
        }


class _Grid:
    """An x, y grid of square cells over ``lo`` (2,) with ``shape`` (nx, ny); cell (i, j) is centred at lo + (i + 0.5, j + 0.5) * cell."""

    def __init__(self, xy: np.ndarray, cell: float) -> None:
        self.cell = cell
        self.lo = xy.min(axis=0) - 0.5 * cell
        self.shape = tuple(int(v) for v in np.floor((xy.max(axis=0) - self.lo) / cell).astype(np.int64) + 1)

    def index(self, xy: np.ndarray) -> np.ndarray:
        """(N, 2) -> (N, 2) int cell indices (clipped to the grid)."""
        ij = np.floor((xy - self.lo) / self.cell).astype(np.int64)
        return np.clip(ij, 0, np.asarray(self.shape) - 1)

    def flat(self, xy: np.ndarray) -> np.ndarray:
        ij = self.index(xy)
        return ij[:, 0] * self.shape[1] + ij[:, 1]

    def centre(self, ij: np.ndarray) -> np.ndarray:
        return self.lo + (np.asarray(ij, dtype=np.float64) + 0.5) * self.cell


def pick_points(splats: Splats, config: PickConfig | None = None, *, footprint: tuple[float, float] | None = None, near=None) -> Picks:
    """Points on the surfaces of ``splats`` (module docstring), in its frame.

    Args:
        splats: the scene (z up, as after ``scene align``).
        config: the grid and thresholds (default :class:`PickConfig`).
        footprint: for the free floor, a robot's ``(height, radius)``
            (:func:`splatplan.robots.footprint.robot_footprint`), replacing ``config.height`` and a
            point's radius 0.
        near: (3,) a point: the nearest surface point to it is reported and walls face it.

    Raises:
        SplatplanError: too few opaque splats, or a footprint that is not two positive numbers.
    """
    cfg = (config or PickConfig()).validate()
    op = np.asarray(splats.opacities, dtype=np.float64)
    m = np.asarray(splats.means, dtype=np.float64)[op >= cfg.opacity_min]  # (M, 3) world
    if len(m) < 10:
        raise SplatplanError(f"only {len(m)} splat(s) have opacity >= {cfg.opacity_min:g}: too few to find surfaces; lower opacity_min (--opacity-min)")
    if footprint is not None and not (len(footprint) == 2 and np.all(np.isfinite(footprint)) and footprint[0] > 0 and footprint[1] >= 0):
        raise SplatplanError(f"footprint {footprint}: expected (height > 0, radius >= 0)")
    span = m[:, :2].max(axis=0) - m[:, :2].min(axis=0)
    cell = float(cfg.cell) if cfg.cell is not None else max(float(span.max()) / 200.0, 1e-6)
    if float(span.max()) / cell > 4000:
        raise SplatplanError(f"cell {cell:g} makes a grid of {span.max() / cell:.0f} cells on a side (at most 4000): choose a larger cell (--cell)")
    fz = fitted_floor_z(splats) if cfg.floor_z is None else float(cfg.floor_z)
    cover = floor_coverage(splats, fz, cfg.step_height)
    floor = FloorInfo(fz, cover, cover >= TerrainConfig().min_floor_coverage)
    q = None if near is None else np.asarray(near, dtype=np.float64).reshape(3)
    ref = q if q is not None else np.array([*(0.5 * (m[:, :2].min(axis=0) + m[:, :2].max(axis=0))), float(np.median(m[:, 2]))])
    grid = _Grid(m[:, :2], cell)
    out = Picks(len(splats), len(m), cfg, cell, floor, ref)
    out.surfaces = _surfaces(m, grid, floor, cfg)
    if cfg.n_walls:
        out.walls = _walls(m, grid, floor, cfg, ref)
    if floor.found:
        height, radius = (cfg.height, 0.0) if footprint is None else (float(footprint[0]), float(footprint[1]))
        out.free = _free_floor(m, grid, fz, height, radius, cfg)
    if q is not None:
        out.near = _near(m, q)
    return out


def _components(mask: np.ndarray, link_x: np.ndarray, link_y: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected pieces of the cells in ``mask`` (nx, ny) joined where ``link_x`` (nx-1, ny) /
    ``link_y`` (nx, ny-1) allow: (count, labels (nx, ny) with -1 outside the mask)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    nx, ny = mask.shape
    idx = np.arange(nx * ny).reshape(nx, ny)
    ex = link_x & mask[:-1] & mask[1:]
    ey = link_y & mask[:, :-1] & mask[:, 1:]
    a = np.concatenate([idx[:-1][ex], idx[:, :-1][ey]])
    b = np.concatenate([idx[1:][ex], idx[:, 1:][ey]])
    g = coo_matrix((np.ones(len(a)), (a, b)), shape=(nx * ny, nx * ny))
    n, lab = connected_components(g, directed=False)
    lab = lab.reshape(nx, ny)
    # renumber the pieces inside the mask 0..k-1 (cells outside it are pieces of their own)
    keep, lab_in = np.unique(lab[mask], return_inverse=True)
    labels = np.full((nx, ny), -1, dtype=np.int64)
    labels[mask] = lab_in
    return len(keep), labels


def _surfaces(m: np.ndarray, grid: _Grid, floor: FloorInfo, cfg: PickConfig) -> list[Surface]:
    from scipy.ndimage import binary_opening, distance_transform_edt, label

    nx, ny = grid.shape
    flat_top = np.full(nx * ny, -np.inf)
    np.maximum.at(flat_top, grid.flat(m[:, :2]), m[:, 2])
    top = flat_top.reshape(nx, ny)  # the height map: the highest opaque mean of each cell
    occ = np.isfinite(top)
    tol = 0.5 * grid.cell
    with np.errstate(invalid="ignore"):
        lx = np.abs(np.diff(top, axis=0)) <= tol
        ly = np.abs(np.diff(top, axis=1)) <= tol
    n, lab = _components(occ, lx, ly)
    w = cfg.min_width_cells
    square = np.ones((w, w), bool)
    found: list[Surface] = []
    for k in range(n):
        ii, jj = np.nonzero(lab == k)
        if len(ii) < w * w:
            continue
        i0, j0 = ii.min(), jj.min()
        piece = np.pad(lab[i0 : ii.max() + 1, j0 : jj.max() + 1] == k, w)
        opened = binary_opening(piece, structure=square) if w > 1 else piece  # the union of w x w squares on it
        parts, n_parts = label(opened)
        for pk in range(1, n_parts + 1):
            part = parts == pk
            pi, pj = np.nonzero(part)
            zs = top[pi - w + i0, pj - w + j0]
            z = float(np.median(zs))
            if floor.found and z < floor.z + cfg.step_height:
                continue  # the floor itself (reported as free floor)
            depth = distance_transform_edt(part)
            bi, bj = np.unravel_index(int(np.argmax(depth)), depth.shape)
            xy = grid.centre(np.array([bi - w + i0, bj - w + j0]))
            lo = grid.centre(np.array([pi.min() - w + i0, pj.min() - w + j0])) - 0.5 * grid.cell
            hi = grid.centre(np.array([pi.max() - w + i0, pj.max() - w + j0])) + 0.5 * grid.cell
            found.append(Surface(np.array([xy[0], xy[1], z]), float(len(pi) * grid.cell**2), lo, hi))
    found.sort(key=lambda s: -float(s.point[2]))
    return found[: cfg.n_surfaces]


def _walls(m: np.ndarray, grid: _Grid, floor: FloorInfo, cfg: PickConfig, ref: np.ndarray) -> list[Wall]:
    """RANSAC lines through the tall cells (module docstring)."""
    nx, ny = grid.shape
    c = grid.cell
    z0 = floor.z + cfg.step_height if floor.found else float(m[:, 2].min())
    band = m[:, 2] >= z0
    mb = m[band]
    if len(mb) == 0:
        return []
    zb = np.floor((mb[:, 2] - z0) / c).astype(np.int64)
    key = grid.flat(mb[:, :2]) * (int(zb.max()) + 1) + zb  # (cell, z bin) pairs
    occupied_cells = np.unique(key) // (int(zb.max()) + 1)
    layers = np.bincount(occupied_cells, minlength=nx * ny)  # distinct z bins per cell
    tall = np.nonzero(layers * c >= cfg.wall_min_height)[0]
    if len(tall) < 2:
        return []
    pts = grid.centre(np.stack([tall // ny, tall % ny], axis=1))  # (T, 2)
    rng = np.random.default_rng(cfg.seed)
    pool = np.ones(len(pts), bool)
    cell_of = grid.flat(mb[:, :2])
    found: list[Wall] = []
    for _ in range(8 * cfg.n_walls + 4):
        if len(found) == 3 * cfg.n_walls or pool.sum() < 2:
            break
        p = pts[pool]
        members = np.nonzero(pool)[0]
        best, best_n = None, -1
        for _h in range(200):
            a, b = rng.choice(len(p), 2, replace=False)
            d = p[b] - p[a]
            nd = float(np.linalg.norm(d))
            if nd < 2 * c:
                continue
            n = np.array([-d[1], d[0]]) / nd
            cnt = int(np.sum(np.abs((p - p[a]) @ n) <= 0.75 * c))
            if cnt > best_n:
                best, best_n = (p[a], d / nd, n), cnt
        if best is None:
            break
        p0, d, n = best
        inl = np.nonzero(np.abs((p - p0) @ n) <= 0.75 * c)[0]
        t = (p[inl] - p0) @ d
        o = np.argsort(t)
        breaks = np.nonzero(np.diff(t[o]) > 2.5 * c)[0]
        runs = np.split(o, breaks + 1)
        run = max(runs, key=len)
        seg = inl[run]
        tr = t[run]
        # the wall's other face and its spill: every pool cell within the thickness band along the run
        tp = (p - p0) @ d
        band_cells = (np.abs((p - p0) @ n) <= 4.0 * c) & (tp >= tr.min() - c) & (tp <= tr.max() + c)
        pool[members[band_cells]] = False
        if len(seg) < 2:
            continue
        # refine the line on the run's cells (principal direction)
        q = p[seg]
        mu = q.mean(axis=0)
        _, _, vt = np.linalg.svd(q - mu, full_matrices=False)
        d = vt[0]
        n = np.array([-d[1], d[0]])
        t = (q - mu) @ d
        length = float(t.max() - t.min() + c)
        if length < cfg.wall_min_length:
            continue
        flat_cells = grid.flat(p[band_cells])
        on = np.isin(cell_of, flat_cells)
        mw = mb[on]
        zlo, zhi = (float(v) for v in np.percentile(mw[:, 2], [2, 98]))
        if np.dot(ref[:2] - mu, n) < 0:
            n = -n
        face = float(np.percentile((mw[:, :2] - mu) @ n, 95))  # the face toward the reference
        s = float(np.clip(np.dot(ref[:2] - mu, d), t.min(), t.max()))
        xy = mu + s * d + face * n
        point = np.array([xy[0], xy[1], float(np.clip(ref[2], zlo, zhi))])
        ends = np.stack([mu + (t.min() - 0.5 * c) * d + face * n, mu + (t.max() + 0.5 * c) * d + face * n])
        found.append(Wall(point, np.array([n[0], n[1], 0.0]), ends, (zlo, zhi), length, length * (zhi - zlo), float(np.linalg.norm(point - ref))))
    # the largest walls, and the nearest one to the reference when it is not among them
    walls = sorted(found, key=lambda w: -w.area)[: cfg.n_walls]
    nearest = min(found, key=lambda w: w.distance, default=None)
    if nearest is not None and not any(w is nearest for w in walls):
        walls.append(nearest)
    return walls


def _free_floor(m: np.ndarray, grid: _Grid, fz: float, height: float, radius: float, cfg: PickConfig) -> FreeFloor:
    from scipy.ndimage import binary_closing, distance_transform_edt, label

    nx, ny = grid.shape
    c = grid.cell
    z = m[:, 2]
    flat = grid.flat(m[:, :2])
    support = np.zeros(nx * ny, bool)
    support[flat[np.abs(z - fz) <= max(cfg.step_height, 0.5 * c)]] = True
    blocked = np.zeros(nx * ny, bool)
    blocked[flat[(z > fz + cfg.step_height) & (z < fz + height)]] = True
    # a sparse floor leaves cells without a floor splat: close holes up to two cells wide
    support = binary_closing(np.pad(support.reshape(nx, ny), 2), structure=np.ones((5, 5), bool))[2:-2, 2:-2]
    free = support & ~blocked.reshape(nx, ny)
    # distance from a free cell's centre to the nearest cell that is not free (the grid's outside
    # counts as not free), less half a cell: the obstacle may lie anywhere in that cell
    clear = (distance_transform_edt(np.pad(free, 1))[1:-1, 1:-1] - 0.5) * c
    fits = free & (clear >= radius)
    lab, n = label(fits)
    regions: list[tuple[np.ndarray, float, float]] = []
    if n:
        sizes = np.bincount(lab.ravel(), minlength=n + 1)[1:]
        for k in np.argsort(-sizes)[: cfg.n_regions]:
            if sizes[k] < 4 and regions:
                break  # a speck between obstacles
            sel = lab == k + 1
            score = np.where(sel, clear, -np.inf)
            ij = np.array(np.unravel_index(int(np.argmax(score)), score.shape))
            xy = grid.centre(ij)
            regions.append((np.array([xy[0], xy[1], fz]), float(sizes[k] * c * c), float(clear[ij[0], ij[1]])))
    cells = grid.centre(np.argwhere(fits)) if n else np.zeros((0, 2))
    return FreeFloor(fz, c, float(height), float(radius), cells, regions)


def _near(m: np.ndarray, q: np.ndarray, k: int = 16) -> NearPoint:
    from scipy.spatial import cKDTree

    tree = cKDTree(m)
    dist, i = tree.query(q)
    p = m[int(i)]
    _, nb = tree.query(p, k=min(k, len(m)))
    nbrs = m[np.atleast_1d(nb)]
    _, _, vt = np.linalg.svd(nbrs - nbrs.mean(axis=0), full_matrices=False)
    n = vt[-1]
    toward = q - p if float(dist) > 1e-9 else np.array([0.0, 0.0, 1.0])
    if np.dot(n, toward) < 0:
        n = -n
    return NearPoint(q, p.copy(), n, float(dist))
