"""Sensed-obstacle memory of the planar base (:class:`ObstacleMemory`): a coarse 2D occupancy grid
sensed around the base with line of sight, *unknown = free*, and the geodesic distance to the goal
over it (:func:`geodesic_field`, with its slow heapq reference): the goal-distance field of
:class:`~splatplan.planners.drive.DriveGoalCost` in the goal-only base MPPI of
:mod:`splatplan.tasks.base` (``BaseConfig.memory``, a field of :class:`MemoryTerms`; :mod:`splatplan.planners.drive` says how).

Frames and units: world frame, metres, z up; grid cell (i, j) along x, y.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .._config import ConfigTerms, bounded
from .._resources import require_bytes
from ..errors import SplatplanError

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..robots.robot import Robot

__all__ = ["MemoryTerms", "ObstacleMemory", "geodesic_field", "line_of_sight"]


#: bytes per grid cell (centres, states, geodesic field, the finer occlusion grid's share): an estimate
MEMORY_BYTES_PER_CELL = 64

class ObstacleMemory:
    """Sensed-obstacle memory of the planar base: a coarse 2D occupancy grid, *unknown = free* at
    the start (the freespace assumption of navigation in unknown terrain, as in D* Lite), and the
    geodesic distance to the goal over it.

    Grid: square cells of ``cell`` metres over the xy box ``lo`` .. ``hi`` (world frame), cell
    (i, j) centred at ``origin + (i + 0.5, j + 0.5) * cell`` with the origin snapped to a multiple
    of ``cell``. :meth:`sense` considers every not yet sensed cell whose centre lies within
    ``radius`` of the base and senses those in line of sight: the cell is **blocked** when the
    robot collides there at every one of ``n_yaws`` headings (``checker.collides_robot``, one
    batched call at yaw 0 for the new cells, one more at the other headings for those that collide
    at yaw 0). Sensed cells are memoised (the scene is static); nothing beyond the radius is sensed.

    Line of sight (``occlusion``, a 2D lidar scanning the plane z = ``sensor_height``): a cell is
    sensed only when the segment from the base (its xy at that height) to the cell's centre crosses
    no *opaque* square of a finer grid (side ``cell / 2``, same origin), ignoring the squares it
    enters within one ``cell`` of the centre. The ray's end is cut so that the surface a blocked
    cell stands on does not hide the cell itself: a wall's inflated surface starts ~0.1 m in front
    of it at n_sigma = 0.75, and the blocked band in front of a wall (where the Go2 collides at
    every heading) is only ~2 cells deep, so a ray that had to reach the centre would see almost
    none of it and the geodesic would leak through half-seen walls; with the cut the band is seen
    from the open side, the wall's far side is not (see :func:`line_of_sight`). A square is opaque
    when a sphere circumscribing it (radius ``cell / 2 / sqrt(2)``, at the sensor height) collides
    with the splats (``checker.collides``, the metric itself, batched over the squares near the
    base that are not yet known, memoised: a cache of metric calls, not knowledge, as the scene is
    static). A visible segment is therefore free by the metric at every point up to the cut (a
    conservative test: squares only grazed by a surface also block; checked against the
    point-sampled :func:`_line_of_sight_reference`). Cells out of sight stay unknown (= free) and
    are considered again every step (the traversal is numpy, ~70 steps over those cells' rays);
    only the cells actually sensed are memoised. ``occlusion=False``: the cells within the radius
    are sensed through walls.

    Field: 8-connected Dijkstra (``scipy.sparse.csgraph.dijkstra``; diagonals only where both
    side cells are free, no corner cutting) from the goal over the not-blocked cells, recomputed
    only when a sense marks new cells blocked. The goal enters through a virtual source linked to
    the free cells within 1.5 cells of it (edge = Euclidean distance). Blocked and unreachable
    cells take the largest value among their filled neighbours plus one cell per ring (so a wall
    never reads closer to the goal than the free side a rollout enters it from). :meth:`distance`
    interpolates bilinearly between cell centres and adds the Euclidean distance outside the grid.
    """

    def __init__(
        self, robot: Robot, checker: CollisionChecker, lo, hi, goal, cell: float = 0.1, radius: float = 2.5, n_yaws: int = 8, inflation_m: float = 0.3, inflation_cost: float = 2.0,
        occlusion: bool = True, sensor_height: float = 0.3,
    ) -> None:  # fmt: skip
        if cell <= 0 or radius <= 0 or n_yaws < 1 or inflation_m < 0 or inflation_cost < 0 or not np.isfinite(sensor_height):
            raise SplatplanError(
                f"obstacle memory: memory_cell_m ({cell}) and sensor_radius_m ({radius}) must be > 0, memory_yaws ({n_yaws}) >= 1, "
                f"memory_inflation_m ({inflation_m}) and memory_inflation_cost ({inflation_cost}) >= 0, sensor_height_m ({sensor_height}) finite"
            )
        self.robot, self.checker = robot, checker
        self.cell, self.radius = float(cell), float(radius)
        self.occlusion, self.sensor_height = bool(occlusion), float(sensor_height)
        self.inflation_m, self.inflation_cost = float(inflation_m), float(inflation_cost)
        self.yaws = np.linspace(0.0, 2 * np.pi, int(n_yaws), endpoint=False)  # (Y,) rad, yaw 0 first
        lo, hi = np.asarray(lo, np.float64)[:2], np.asarray(hi, np.float64)[:2]
        self.origin = np.floor(lo / self.cell) * self.cell  # (2,) world xy of the grid's corner
        n_cells = float(np.prod(np.maximum(np.ceil((hi - self.origin) / self.cell), 1)))
        require_bytes(n_cells * 4 * MEMORY_BYTES_PER_CELL, f"the obstacle memory's grid ({n_cells:.3g} cells of {self.cell:g} m)", "the resolution: a larger --base-memory-cell-m")
        self.shape = tuple(int(v) for v in np.maximum(np.ceil((hi - self.origin) / self.cell), 1))  # (NX, NY)
        ix, iy = np.meshgrid(np.arange(self.shape[0]), np.arange(self.shape[1]), indexing="ij")
        self.centers = self.origin + (np.stack([ix, iy], axis=-1) + 0.5) * self.cell  # (NX, NY, 2) world xy, metres
        self.sensed = np.zeros(self.shape, bool)  # (NX, NY) checked once
        self.blocked = np.zeros(self.shape, bool)  # (NX, NY) robot collides at every heading
        self.goal = np.asarray(goal, np.float64).reshape(-1)[:2].copy()
        # line of sight: squares of half a cell over the same box, opacity at the sensor height
        self.sight_res = 0.5 * self.cell  # m, side of the opacity squares
        self.sight_shape = (2 * self.shape[0], 2 * self.shape[1])  # (MX, MY)
        self.opacity_known = np.zeros(self.sight_shape, bool)  # (MX, MY) the metric was asked
        self.opaque = np.zeros(self.sight_shape, bool)  # (MX, MY) a surface within the square's circumscribed sphere
        self.stats: dict[str, Any] = {"n_sensed": 0, "n_blocked": 0, "n_queries": 0, "n_recomputes": 0, "sense_s": 0.0, "field_s": 0.0, "first_sense_s": None,
                      "n_rays": 0, "n_occluded": 0, "n_opacity_queries": 0, "sight_s": 0.0}  # fmt: skip
        self._recompute()

    # ---------------------------------------------------------------- sensing
    def sense(self, xy) -> int:
        """Sense the unsensed cells within ``radius`` of ``xy`` (2,); recompute the field when any
        is blocked. Returns the number of newly blocked cells."""
        t0 = time.perf_counter()
        xy = np.asarray(xy, np.float64).reshape(-1)[:2]
        r_cells = int(np.ceil(self.radius / self.cell)) + 1
        c = np.floor((xy - self.origin) / self.cell).astype(int)
        a0, b0 = np.maximum(c - r_cells, 0), np.minimum(c + r_cells + 1, self.shape)
        if np.any(b0 <= a0):
            return 0
        win = (slice(a0[0], b0[0]), slice(a0[1], b0[1]))
        new = (~self.sensed[win]) & (np.linalg.norm(self.centers[win] - xy, axis=-1) <= self.radius)
        idx = np.argwhere(new) + a0  # (C, 2) cell indices
        if self.occlusion and len(idx):
            idx = idx[self.visible(xy, self.centers[idx[:, 0], idx[:, 1]])]
        if not len(idx):
            self.stats["sense_s"] += time.perf_counter() - t0
            return 0
        blocked = self._blocked_at(self.centers[idx[:, 0], idx[:, 1]])  # (C,)
        self.sensed[idx[:, 0], idx[:, 1]] = True
        self.blocked[idx[:, 0], idx[:, 1]] = blocked
        n_new = int(blocked.sum())
        self.stats["n_sensed"] += len(idx)
        self.stats["n_blocked"] += n_new
        self.stats["sense_s"] += time.perf_counter() - t0
        if self.stats["first_sense_s"] is None:  # the whole disc at once: the one large sense
            self.stats["first_sense_s"] = time.perf_counter() - t0
        if n_new:
            self._recompute()
        return n_new

    def visible(self, xy, targets) -> np.ndarray:
        """(C,) True where the segment from the sensor at ``xy`` (2,) to ``targets`` (C, 2) (world
        xy, metres, both at ``sensor_height``) is free of opaque squares up to one cell before its
        end (asks the metric for the squares within the sensor radius not yet known)."""
        t0 = time.perf_counter()
        xy = np.asarray(xy, np.float64).reshape(-1)[:2]
        targets = np.asarray(targets, np.float64).reshape(-1, 2)
        reach = max(self.radius, float(np.linalg.norm(targets - xy, axis=1).max(initial=0.0)))
        self._sense_opacity(xy, reach)
        vis = line_of_sight(self.opaque, self.origin, self.sight_res, xy, targets, end=self.cell)
        self.stats["n_rays"] += len(targets)
        self.stats["n_occluded"] += int((~vis).sum())
        self.stats["sight_s"] += time.perf_counter() - t0
        return vis

    def _sense_opacity(self, xy: np.ndarray, reach: float) -> None:
        """Ask the metric for the opacity of every unknown square that a segment from ``xy`` of
        length ``reach`` can enter (squares within reach + one square of it)."""
        res = self.sight_res
        r = int(np.ceil(reach / res)) + 2
        c = np.floor((xy - self.origin) / res).astype(int)
        a0, b0 = np.maximum(c - r, 0), np.minimum(c + r + 1, self.sight_shape)
        if np.any(b0 <= a0):
            return
        ii, jj = np.meshgrid(np.arange(a0[0], b0[0]), np.arange(a0[1], b0[1]), indexing="ij")
        ctr = self.origin + (np.stack([ii, jj], axis=-1) + 0.5) * res  # (w, h, 2) world xy, metres
        ask = ~self.opacity_known[a0[0] : b0[0], a0[1] : b0[1]] & (np.linalg.norm(ctr - xy, axis=-1) <= reach + res)
        if not ask.any():
            return
        p = ctr[ask]  # (S, 2)
        pts = np.concatenate([p, np.full((len(p), 1), self.sensor_height)], axis=1)  # (S, 3) world, metres
        hit = np.asarray(self.checker.collides(pts, None, res / np.sqrt(2.0)))  # (S,) sphere circumscribing the square
        i, j = ii[ask], jj[ask]
        self.opaque[i, j] = hit
        self.opacity_known[i, j] = True
        self.stats["n_opacity_queries"] += len(p)

    def _blocked_at(self, xy: np.ndarray) -> np.ndarray:
        """(C,) True where the robot at xy (C, 2) collides at every heading of ``yaws``."""
        q = np.concatenate([xy, np.full((len(xy), 1), self.yaws[0])], axis=1)  # (C, 3) x, y, yaw
        blocked = np.any(np.asarray(self.checker.collides_robot(self.robot, q)), axis=-1)  # (C,)
        self.stats["n_queries"] += len(q)
        rest = np.flatnonzero(blocked)
        if len(rest) and len(self.yaws) > 1:  # the other headings only where yaw 0 collides
            y = self.yaws[1:]
            q = np.concatenate([np.repeat(xy[rest], len(y), axis=0), np.tile(y, len(rest))[:, None]], axis=1)  # (R * (Y-1), 3)
            hit = np.asarray(self.checker.collides_robot(self.robot, q)).any(axis=-1).reshape(len(rest), len(y))
            self.stats["n_queries"] += len(q)
            blocked[rest] = hit.all(axis=1)
        return blocked

    # ---------------------------------------------------------------- field
    def _recompute(self) -> None:
        t0 = time.perf_counter()
        self.cost = np.ones(self.shape)  # (NX, NY) per-cell step cost factor >= 1
        if self.inflation_m > 0 and self.inflation_cost > 0 and self.blocked.any():
            from scipy.ndimage import distance_transform_edt

            d = distance_transform_edt(~self.blocked) * self.cell  # (NX, NY) m from each cell centre to the nearest blocked one
            self.cost += self.inflation_cost * np.clip(1.0 - (d - self.cell) / self.inflation_m, 0.0, 1.0)
        self.field = geodesic_field(self.blocked, self.origin, self.cell, self.goal, self.cost)  # (NX, NY) metres (cost-weighted)
        gx, gy = np.gradient(self.field, self.cell)
        self._grad = np.stack([gx, gy], axis=-1)  # (NX, NY, 2) d field / d xy
        self.stats["n_recomputes"] += 1
        self.stats["field_s"] += time.perf_counter() - t0

    def _bilinear(self, grid: np.ndarray, xy: np.ndarray):
        """Bilinear interpolation of ``grid`` (NX, NY, ...) at xy (..., 2) clamped into the grid;
        also returns the distance from xy to its clamped point (m)."""
        u = (xy - self.origin) / self.cell - 0.5  # (..., 2) continuous cell coordinates
        uc = np.clip(u, 0.0, np.asarray(self.shape) - 1.0)
        i0 = np.minimum(np.floor(uc).astype(int), np.asarray(self.shape) - 2).clip(0)
        f = uc - i0
        i1 = np.minimum(i0 + 1, np.asarray(self.shape) - 1)
        fx, fy = f[..., 0], f[..., 1]
        if grid.ndim == 3:
            fx, fy = fx[..., None], fy[..., None]
        v = (grid[i0[..., 0], i0[..., 1]] * (1 - fx) * (1 - fy) + grid[i1[..., 0], i0[..., 1]] * fx * (1 - fy)
             + grid[i0[..., 0], i1[..., 1]] * (1 - fx) * fy + grid[i1[..., 0], i1[..., 1]] * fx * fy)  # fmt: skip
        return v, np.linalg.norm(u - uc, axis=-1) * self.cell

    def distance(self, xy) -> np.ndarray:
        """(...,) geodesic distance (m) to the goal from xy (..., 2), world frame."""
        v, out = self._bilinear(self.field, np.asarray(xy, np.float64))
        return v + out

    def heading(self, xy) -> np.ndarray:
        """(...,) direction (rad, world frame) of steepest descent of the field at xy (..., 2)."""
        g, _ = self._bilinear(self._grad, np.asarray(xy, np.float64))
        return np.arctan2(-g[..., 1], -g[..., 0])


def line_of_sight(opaque: np.ndarray, origin, res: float, p0, p1, end: float = 0.0) -> np.ndarray:
    """(C,) True where the segment from ``p0`` (2,) to each of ``p1`` (C, 2) (world xy, metres)
    enters no ``opaque`` square (MX, MY) of the grid of side ``res`` from ``origin`` (2,), except
    squares it first enters within ``end`` metres of its end point (a segment no longer than
    ``end`` is always visible; squares outside the grid are clear).

    Exact grid traversal (Amanatides & Woo, vectorised over the segments still running, one numpy
    step per square crossed; a segment stops at its first opaque square or at the cut): every square the segment passes through is tested, so every point of a
    visible segment up to ``end`` before p1 lies in a clear square. A segment through a square's
    corner exactly visits one of the two side squares. Slow reference: :func:`_line_of_sight_reference`."""
    p0 = np.asarray(p0, np.float64).reshape(2)
    p1 = np.asarray(p1, np.float64).reshape(-1, 2)
    u0 = (p0 - np.asarray(origin, np.float64)) / res  # (2,) grid units
    d = (p1 - p0) / res  # (C, 2) grid units
    length = np.linalg.norm(d, axis=1) * res  # (C,) m
    t_end = 1.0 - end / np.maximum(length, 1e-12)  # (C,) squares entered at t <= t_end are tested
    cell = np.broadcast_to(np.floor(u0).astype(np.int64), d.shape).copy()  # (C, 2) current square
    n_steps = np.abs(np.floor(u0 + d).astype(np.int64) - cell).sum(axis=1)  # (C,) squares to cross
    step = np.sign(d).astype(np.int64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_delta = np.where(d != 0, 1.0 / np.abs(d), np.inf)  # (C, 2) t per square along each axis
        t_max = np.where(d > 0, (cell + 1 - u0) / d, np.where(d < 0, (cell - u0) / d, np.inf))  # (C, 2) t of the next boundary
    mx, my = opaque.shape

    def hits(c):
        inside = (c[:, 0] >= 0) & (c[:, 0] < mx) & (c[:, 1] >= 0) & (c[:, 1] < my)
        out = np.zeros(len(c), bool)
        out[inside] = opaque[c[inside, 0], c[inside, 1]]
        return out

    blocked = hits(cell) & (t_end >= 0.0)  # (C,) the sensor's own square, entered at t = 0
    act = np.flatnonzero(~blocked & (n_steps > 0))  # rays still running
    cell, t_max, t_delta, step, t_end, n_left = cell[act], t_max[act], t_delta[act], step[act], t_end[act], n_steps[act]
    while len(act):
        rows = np.arange(len(act))
        ax = (t_max[:, 1] < t_max[:, 0]).astype(np.int64)  # (A,) axis of the next boundary (x on ties)
        entry = t_max[rows, ax]  # (A,) t at which the next square is entered
        cell[rows, ax] += step[rows, ax]
        t_max[rows, ax] += t_delta[rows, ax]
        n_left = n_left - 1
        live = entry <= t_end  # squares entered past the cut are not tested, nor any after them
        hit = live & hits(cell)
        blocked[act[hit]] = True
        keep = live & ~hit & (n_left > 0)
        act, cell, t_max, t_delta, step, t_end, n_left = act[keep], cell[keep], t_max[keep], t_delta[keep], step[keep], t_end[keep], n_left[keep]
    return ~blocked


def _line_of_sight_reference(checker, height: float, p0, p1, end: float = 0.0, spacing: float = 0.005, radius: float = 1e-4) -> np.ndarray:
    """Slow reference of :class:`ObstacleMemory`'s line of sight: (C,) True where no point sampled
    every ``spacing`` m along the segment from ``p0`` (2,) to ``p1`` (C, 2) at z = ``height``
    (world, metres), at least ``end`` m before p1, collides by the metric (``checker.collides``
    with spheres of ``radius``). :func:`line_of_sight` over squares opaque by their circumscribed
    sphere is conservative against it (visible there implies visible here)."""
    p0 = np.asarray(p0, np.float64).reshape(2)
    out = []
    for q in np.asarray(p1, np.float64).reshape(-1, 2):
        L = float(np.linalg.norm(q - p0))
        if L <= end:
            out.append(True)
            continue
        t = np.linspace(0.0, 1.0 - end / L, max(2, int(np.ceil((L - end) / spacing)) + 1))
        xy = p0 + t[:, None] * (q - p0)
        pts = np.concatenate([xy, np.full((len(xy), 1), height)], axis=1)
        out.append(not np.asarray(checker.collides(pts, None, radius)).any())
    return np.asarray(out, bool)


def geodesic_field(blocked: np.ndarray, origin, cell: float, goal, cost: np.ndarray | None = None) -> np.ndarray:
    """(NX, NY) geodesic distance (m) from every cell centre to ``goal`` (2,) over the not-blocked
    cells of ``blocked`` (NX, NY), each step weighted by the mean ``cost`` (NX, NY) >= 1 of its two
    cells (None: 1, the plain path length; see :class:`ObstacleMemory`; slow reference:
    :func:`_geodesic_field_reference`)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    nx, ny = blocked.shape
    n = nx * ny
    free = ~blocked
    cost = np.ones((nx, ny)) if cost is None else np.asarray(cost, np.float64)
    ids = np.arange(n).reshape(nx, ny)
    rows, cols, w = [], [], []
    for dx, dy in ((1, 0), (0, 1), (1, 1), (1, -1)):  # each undirected edge once: (i, j) -> (i + dx, j + dy)
        ra, rb = slice(0, nx - dx), slice(dx, nx)
        ca, cb = slice(max(0, -dy), ny - max(0, dy)), slice(max(0, dy), ny + min(0, dy))
        ok = free[ra, ca] & free[rb, cb]
        if dx and dy:  # diagonal: both side cells (i + dx, j) and (i, j + dy) free
            ok &= free[rb, ca] & free[ra, cb]
        rows.append(ids[ra, ca][ok])
        cols.append(ids[rb, cb][ok])
        step = cell * (np.sqrt(2.0) if dx and dy else 1.0)
        w.append(step * 0.5 * (cost[ra, ca] + cost[rb, cb])[ok])
    g = np.asarray(goal, np.float64)[:2]
    centers = np.asarray(origin, np.float64) + (np.stack(np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij"), -1) + 0.5) * cell
    d_goal = np.linalg.norm(centers - g, axis=-1)  # (NX, NY)
    near = free & (d_goal <= 1.5 * cell)
    if not near.any():  # the goal's cells are all blocked: link the nearest cell anyway
        near = d_goal == d_goal.min()
    rows.append(np.full(int(near.sum()), n))
    cols.append(ids[near])
    w.append(np.maximum(d_goal[near] * cost[near], 1e-9))  # a stored 0 would read as no edge
    graph = coo_matrix((np.concatenate(w), (np.concatenate(rows), np.concatenate(cols))), shape=(n + 1, n + 1)).tocsr()
    dist = dijkstra(graph, directed=False, indices=n)[:n].reshape(nx, ny)
    return _fill_undefined(dist, cell)


def _fill_undefined(dist: np.ndarray, cell: float) -> np.ndarray:
    """Blocked / unreachable cells (inf) take the largest finite 3x3 neighbour plus one cell, ring
    by ring outwards from the reachable free space."""
    from scipy.ndimage import grey_dilation

    f = np.where(np.isfinite(dist), dist, -np.inf)
    if not np.isfinite(f).any():
        return np.zeros_like(dist)
    while True:
        und = ~np.isfinite(f)
        if not und.any():
            return f
        d = grey_dilation(f, size=(3, 3), mode="nearest")
        ring = und & np.isfinite(d)
        f[ring] = d[ring] + cell


def _geodesic_field_reference(blocked: np.ndarray, origin, cell: float, goal, cost: np.ndarray | None = None) -> np.ndarray:
    """Slow, obviously correct reference of :func:`geodesic_field` (heapq Dijkstra over dicts)."""
    import heapq

    nx, ny = blocked.shape
    cost = np.ones((nx, ny)) if cost is None else cost
    g = np.asarray(goal, np.float64)[:2]
    center = lambda i, j: np.asarray(origin, np.float64) + (np.array([i, j]) + 0.5) * cell  # noqa: E731
    dist = np.full((nx, ny), np.inf)
    heap: list[tuple[float, int, int]] = []
    starts = [(i, j) for i in range(nx) for j in range(ny) if not blocked[i, j] and np.linalg.norm(center(i, j) - g) <= 1.5 * cell]
    if not starts:
        dd = {(i, j): np.linalg.norm(center(i, j) - g) for i in range(nx) for j in range(ny)}
        m = min(dd.values())
        starts = [k for k, v in dd.items() if v == m]
    for i, j in starts:
        d0 = float(np.linalg.norm(center(i, j) - g)) * cost[i, j]
        if d0 < dist[i, j]:
            dist[i, j] = d0
            heapq.heappush(heap, (d0, i, j))
    while heap:
        d, i, j = heapq.heappop(heap)
        if d > dist[i, j] or blocked[i, j]:
            continue
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                a, b = i + di, j + dj
                if (di, dj) == (0, 0) or not (0 <= a < nx and 0 <= b < ny) or blocked[a, b]:
                    continue
                if di and dj and (blocked[i + di, j] or blocked[i, j + dj]):
                    continue
                nd = d + cell * (np.sqrt(2.0) if di and dj else 1.0) * 0.5 * (cost[i, j] + cost[a, b])
                if nd < dist[a, b] - 1e-12:
                    dist[a, b] = nd
                    heapq.heappush(heap, (nd, a, b))
    out = dist.copy()
    while not np.isfinite(out).all():
        nxt = out.copy()
        for i in range(nx):
            for j in range(ny):
                if np.isfinite(out[i, j]):
                    continue
                nb = [out[a, b] for a in range(max(i - 1, 0), min(i + 2, nx)) for b in range(max(j - 1, 0), min(j + 2, ny)) if np.isfinite(out[a, b])]
                if nb:
                    nxt[i, j] = max(nb) + cell
        out = nxt
    return out


@dataclass
class MemoryTerms(ConfigTerms):
    """The sensed-obstacle memory's fields of a driving task's config (flat in it: ``--base-memory``)."""

    #: sensed-obstacle memory (off by default): a coarse occupancy grid, unknown = free, filled with
    #: the cells sensed within sensor_radius_m of the base every MPC step; the goal cost then uses
    #: the geodesic distance to the goal on it instead of the straight line (see planners.memory)
    memory: bool = False
    #: memory: sensing radius around the base (m); nothing beyond it is sensed
    sensor_radius_m: float = bounded(2.5, gt=0)
    #: memory: grid cell size (m)
    memory_cell_m: float = bounded(0.1, gt=0)
    #: memory: a cell is blocked when the base collides there at every one of this many headings
    memory_yaws: int = bounded(8, ge=1)
    #: memory: cells closer than this (m) to a blocked cell cost more to cross (an inflation layer,
    #: as in navigation costmaps: the geodesic keeps to the middle of passages and doorways)
    memory_inflation_m: float = bounded(0.3, ge=0)
    #: memory: extra cost factor of a cell next to a blocked one (falls linearly to 0 at memory_inflation_m)
    memory_inflation_cost: float = bounded(2.0, ge=0)
    #: memory: line of sight, like a 2D lidar at sensor_height_m: a cell is sensed only once the segment from
    #: the base to its centre is free of scene surfaces (by the metric) up to one cell before the centre;
    #: cells out of sight stay unknown (= free) and are tried again every step (False: senses through walls)
    sensor_occlusion: bool = True
    #: memory: height of the sensor's scan plane above the floor (m; the Go2's body spans ~0.28-0.52 m,
    #: its legs below; lower obstacles are seen over, as a lidar on the body would)
    sensor_height_m: float = bounded(0.3, ge=0)

    def obstacle_memory(self, robot: Robot, checker: CollisionChecker, lo, hi, goal) -> ObstacleMemory | None:
        """The :class:`ObstacleMemory` of the box ``lo``..``hi`` (world, m) with the goal ``goal`` (2,), or None when ``memory`` is off."""
        if not self.memory:
            return None
        return ObstacleMemory(robot, checker, lo, hi, goal, cell=self.memory_cell_m, radius=self.sensor_radius_m, n_yaws=self.memory_yaws, inflation_m=self.memory_inflation_m,
                              inflation_cost=self.memory_inflation_cost, occlusion=self.sensor_occlusion, sensor_height=self.sensor_height_m)  # fmt: skip
