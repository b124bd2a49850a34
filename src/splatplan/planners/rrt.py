"""Batched RRT (paper Sec. II-E) on the CollisionSplatting checker.

Each iteration draws ``batch_size`` samples (goal-biased), finds the nearest tree node of every
sample (one vectorised distance matrix), steers from it by at most ``stride``, discretises every
new edge at ``edge_resolution`` and checks all edges in **one** batched ``checker.collides`` call
on an array shaped (N_batch, N_edge_pts, N_links). Collision-free edges become new nodes.

* **Goal mode** (``goal`` given): new nodes within ``connect_radius`` of the goal try a direct,
  collision-checked edge to the goal (one batched call); the first iteration with a free one ends
  the search and the goal itself becomes the path's last vertex. The path can then be shortcut
  greedily (batched edge checks).
* **Exploration mode** (``goal=None``): grows the tree until ``max_nodes`` / ``max_iters`` /
  ``time_budget_s`` and returns it (nodes + parents), e.g. for image-goal retrieval (E6).

Configurations are points of a D-dimensional box (D = len(start)); a ``link_poses`` callable maps
configurations (..., D) to robot link ellipsoids (centers (..., L, 3), quats (..., L, 4) wxyz or
None, semi_axes (L, 3)) -- by default a sphere of radius ``radius`` centred at the configuration
(D = 3, world frame, scene units). Any :class:`~splatplan.planners.dynamics.Dynamics`'s
``link_poses`` works too (e.g. a :class:`PlanarBase` over (x, y, yaw)). Distances (stride,
resolution, tolerances) are Euclidean in configuration space.

The tree lives in preallocated numpy arrays on the CPU, grown in place. That is deliberate: the
tree holds at most a few ten thousand nodes, nearest-neighbour search over it is a (32 x n)
distance matrix, and the expensive part (collision checks) runs on the checker's own device.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.spatial.distance import cdist

from ..errors import PlanningError, SplatplanError
from .dynamics import sphere_links

LinkPoses = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray | None, np.ndarray]]


@dataclass
class RRTConfig:
    """Knobs of the batched RRT. Distances are in configuration-space units (scene units for a
    position robot)."""

    #: samples drawn (and edges checked) per iteration; the paper grows 32 nodes at a time
    batch_size: int = 32
    #: maximum edge length: a sample farther than this from its nearest node is pulled back to it
    stride: float = 0.03
    #: spacing of the collision checks along an edge; None = a quarter of the robot's smallest
    #: semi-axis for the default sphere robot (whose inner edge samples are checked with the
    #: sphere grown by half the spacing, <= r/8), half of it for other robots
    edge_resolution: float | None = None
    #: probability that a sample is the goal itself (goal mode only)
    goal_bias: float = 0.1
    #: a node closer than this to the goal ends the search even if the last edge to the goal is not
    #: free (the path then ends at that node); 0 = the path must reach the goal exactly
    goal_tolerance: float = 0.0
    #: new nodes within this distance of the goal try a direct collision-checked edge to it;
    #: None = 4 * stride
    connect_radius: float | None = None
    #: iteration budget
    max_iters: int = 5000
    #: node budget (the tree arrays are preallocated with this size)
    max_nodes: int = 20000
    #: wall-clock budget in seconds (None = unlimited)
    time_budget_s: float | None = 60.0
    #: seed of the sampler
    seed: int = 0
    #: sampling box lower corner (D,); None = the scene's splat bounds united with start/goal.
    #: A side with lo == hi freezes that coordinate (e.g. planar planning at a fixed z)
    box_lo: tuple[float, ...] | None = None
    #: sampling box upper corner (D,); see box_lo
    box_hi: tuple[float, ...] | None = None
    #: greedily shortcut the found path (batched edge checks at edge_resolution)
    shortcut: bool = True

    def validate(self) -> "RRTConfig":
        if self.batch_size < 1:
            raise SplatplanError(f"RRTConfig.batch_size must be >= 1, got {self.batch_size}")
        if not self.stride > 0:
            raise SplatplanError(f"RRTConfig.stride must be > 0, got {self.stride}")
        if self.edge_resolution is not None and not self.edge_resolution > 0:
            raise SplatplanError(f"RRTConfig.edge_resolution must be > 0, got {self.edge_resolution}")
        if not 0.0 <= self.goal_bias <= 1.0:
            raise SplatplanError(f"RRTConfig.goal_bias must lie in [0, 1], got {self.goal_bias}")
        if self.goal_tolerance < 0:
            raise SplatplanError(f"RRTConfig.goal_tolerance must be >= 0, got {self.goal_tolerance}")
        if self.max_nodes < 2 or self.max_iters < 1:
            raise SplatplanError("RRTConfig.max_nodes must be >= 2 and max_iters >= 1")
        return self


@dataclass
class PlanResult:
    """Outcome of a planning call.

    Attributes:
        success: goal mode: a path was found; exploration mode: the tree was grown (always True).
        path: (P, D) path vertices from start to goal (empty (0, D) when none was found or in
            exploration mode); after refinement a densely sampled smooth curve.
        length: Euclidean length of ``path`` (configuration units); inf when no path.
        time_s: wall-clock seconds of the whole call (search + shortcut + refinement).
        n_nodes: nodes in the tree (root included).
        n_iters: RRT iterations run.
        tree_nodes: (n_nodes, D) tree node configurations.
        tree_parents: (n_nodes,) int64 parent index of each node, -1 for the root.
        message: why it stopped, in words.
        path_rrt: (P0, D) the raw tree path before shortcutting / refinement (goal mode).
        refined: whether ``path`` is the accepted output of the zeroth-order refinement.
    """

    success: bool
    path: np.ndarray
    length: float
    time_s: float
    n_nodes: int
    n_iters: int
    tree_nodes: np.ndarray
    tree_parents: np.ndarray
    message: str = ""
    path_rrt: np.ndarray | None = None
    refined: bool = False
    info: dict = field(default_factory=dict)


def path_length(path: np.ndarray) -> float:
    """Sum of segment lengths of a polyline (P, D); 0 for P < 2."""
    p = np.asarray(path, dtype=np.float64)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) if len(p) > 1 else 0.0


def edge_points(a: np.ndarray, b: np.ndarray, resolution: float, include_start: bool = False) -> np.ndarray:
    """Points along E straight edges a[e] -> b[e], spaced at most ``resolution`` apart.

    Every edge gets the same number of points ``n = ceil(max_len / resolution)`` (shorter edges are
    sampled more densely), at parameters ``k / n`` for k = 1..n (k = 0..n with include_start), so
    the edge's end point is always included.

    Args:
        a: (E, D) edge starts.
        b: (E, D) edge ends.
        resolution: maximum spacing (configuration units).

    Returns:
        (E, n_pts, D) points.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    lmax = float(np.linalg.norm(b - a, axis=-1).max()) if len(a) else 0.0
    n = max(1, int(math.ceil(lmax / resolution - 1e-9)))
    t = np.arange(0 if include_start else 1, n + 1) / n  # (n_pts,)
    return a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]


class EdgeChecker:
    """Batched straight-edge collision checks of a robot (``link_poses``) against a checker.

    With ``inflate`` (meant for position robots, where configuration distance = workspace
    distance), the samples *inside* an edge are checked with every semi-axis grown by half the
    sample spacing: any point of the edge lies within that distance of a sample, so the edge is
    free between the samples too, not only at them (exact for n_sigma = 0, where s2 < 1 means a
    splat mean inside the link). The edge's end point is checked with the true size.
    """

    def __init__(self, checker, link_poses: LinkPoses, resolution: float, inflate: bool = False) -> None:
        self.checker = checker
        self.link_poses = link_poses
        self.resolution = float(resolution)
        self.inflate = bool(inflate)
        self.n_queries = 0  # link poses checked so far

    def configs_collide(self, configs: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """(..., D) -> bool (...): any link in collision (semi-axes grown by ``margin``)."""
        centers, quats, axes = self.link_poses(configs)  # (..., L, 3)
        hit = self.checker.collides(centers, quats, np.asarray(axes) + margin)  # (..., L)
        self.n_queries += hit.size
        return hit.any(axis=-1)

    def edges_free(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(E, D), (E, D) -> bool (E,): True where the whole edge (end point included, start
        excluded) is collision-free at ``resolution``. One batched checker call (two with inflate)."""
        if len(a) == 0:
            return np.zeros(0, dtype=bool)
        pts = edge_points(a, b, self.resolution)  # (E, n_pts, D), the last point is b
        if not self.inflate:
            return ~self.configs_collide(pts).any(axis=1)
        spacing = float(np.linalg.norm(b - a, axis=-1).max()) / pts.shape[1]
        inner = self.configs_collide(pts[:, :-1], margin=0.5 * spacing).any(axis=1) if pts.shape[1] > 1 else np.zeros(len(a), bool)
        return ~(inner | self.configs_collide(pts[:, -1]))

    def path_free(self, path: np.ndarray) -> bool:
        """Whether every point of a polyline (P, D), sampled at ``resolution``, is collision-free."""
        p = np.asarray(path, dtype=np.float64)
        if len(p) == 1:
            return not bool(self.configs_collide(p).any())
        return bool(self.edges_free(p[:-1], p[1:]).all()) and not bool(self.configs_collide(p[:1]).any())


def check_endpoint(checker, link_poses: LinkPoses, x: np.ndarray, what: str) -> None:
    """Raise :class:`PlanningError` when configuration ``x`` (D,) is in collision."""
    centers, quats, axes = link_poses(x[None])
    res = checker.query(centers, quats, axes)  # (1, L)
    if bool(np.any(res.in_collision)):
        j = int(np.argmin(res.min_s2[0]))
        raise PlanningError(
            f"the {what} {np.array2string(x, precision=4)} is in collision: min_s2 = {float(res.min_s2[0, j]):.4g} < 1 "
            f"({int(res.n_colliding[0, j])} splat(s) inside the robot at n_sigma = {checker.n_sigma:g}); "
            f"move the {what}, shrink the robot or lower n_sigma"
        )


def shortcut_path(edges: EdgeChecker, path: np.ndarray) -> np.ndarray:
    """Greedy shortcutting: from each kept vertex jump to the farthest vertex reachable by a free
    straight edge (all candidate edges of a vertex checked in one batched call).

    The result is collision-free at the checker's resolution whenever the input was, never longer
    than the input, and keeps both endpoints.
    """
    p = np.asarray(path, dtype=np.float64)
    if len(p) <= 2:
        return p.copy()
    out = [p[0]]
    i = 0
    while i < len(p) - 1:
        cand = np.arange(i + 2, len(p))
        j = i + 1
        if cand.size:
            free = edges.edges_free(np.repeat(p[i : i + 1], cand.size, axis=0), p[cand])
            if free.any():
                j = int(cand[np.nonzero(free)[0].max()])
        out.append(p[j])
        i = j
    return np.asarray(out)


class RRT:
    """Batched RRT over a box of D-dimensional configurations (see the module docstring).

    Args:
        checker: a :class:`~splatplan.metric.CollisionChecker` (any backend).
        config: :class:`RRTConfig`.
        link_poses: configurations (..., D) -> (centers (..., L, 3), quats or None, semi_axes
            (L, 3)); None = a sphere of ``radius`` centred at the (3-D) configuration.
        radius: sphere radius (scene units) when ``link_poses`` is None.
    """

    def __init__(self, checker, config: RRTConfig | None = None, link_poses: LinkPoses | None = None, radius: float = 0.015) -> None:
        self.checker = checker
        self.config = (config or RRTConfig()).validate()
        self.link_poses = link_poses if link_poses is not None else sphere_links(radius)
        #: position robot (the default sphere): edges are checked between their samples too
        self.inflate_edges = link_poses is None

    # ------------------------------------------------------------------ setup
    def _box(self, start: np.ndarray, goal: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        cfg = self.config
        d = start.size
        if cfg.box_lo is None or cfg.box_hi is None:
            if d != 3:
                raise PlanningError(f"give RRTConfig.box_lo / box_hi for a {d}-D configuration space")
            lo, hi = self.checker.scene.bounds()
            pts = [start] + ([goal] if goal is not None else [])
            lo = np.minimum(lo, np.min(pts, axis=0)) if cfg.box_lo is None else np.asarray(cfg.box_lo, dtype=np.float64)
            hi = np.maximum(hi, np.max(pts, axis=0)) if cfg.box_hi is None else np.asarray(cfg.box_hi, dtype=np.float64)
        else:
            lo = np.asarray(cfg.box_lo, dtype=np.float64).reshape(-1)
            hi = np.asarray(cfg.box_hi, dtype=np.float64).reshape(-1)
        if lo.shape != (d,) or hi.shape != (d,):
            raise PlanningError(f"the sampling box has dimension {lo.shape}/{hi.shape}, the start has {d}")
        if np.any(hi < lo):
            raise PlanningError(f"the sampling box is empty: lo {lo} > hi {hi} somewhere")
        for name, x in (("start", start), ("goal", goal)):
            if x is None:
                continue
            tol = 1e-9 * max(1.0, float(np.abs(x).max()))
            if np.any(x < lo - tol) or np.any(x > hi + tol):
                raise PlanningError(
                    f"the {name} {np.array2string(x, precision=4)} lies outside the sampling box "
                    f"lo={np.array2string(lo, precision=4)} hi={np.array2string(hi, precision=4)} "
                    f"(a frozen coordinate lo == hi must equal the {name}'s)"
                )
        return lo, hi

    def _resolution(self, start: np.ndarray) -> float:
        if self.config.edge_resolution is not None:
            return float(self.config.edge_resolution)
        _, _, axes = self.link_poses(start[None])
        return (0.25 if self.inflate_edges else 0.5) * float(np.min(axes))

    # ------------------------------------------------------------------ search
    def plan(self, start, goal=None) -> PlanResult:
        """Grow a tree from ``start``; towards ``goal`` (goal mode) or everywhere (goal=None).

        Raises:
            PlanningError: start or goal in collision, outside the sampling box, or a bad box.
        """
        t0 = time.perf_counter()
        cfg = self.config
        start = np.asarray(start, dtype=np.float64).reshape(-1)
        goal = None if goal is None else np.asarray(goal, dtype=np.float64).reshape(-1)
        d = start.size
        if goal is not None and goal.shape != start.shape:
            raise PlanningError(f"start has {d} coordinates but goal has {goal.size}")
        if not np.all(np.isfinite(start)) or (goal is not None and not np.all(np.isfinite(goal))):
            raise PlanningError("start and goal must be finite")
        lo, hi = self._box(start, goal)
        edges = EdgeChecker(self.checker, self.link_poses, self._resolution(start), inflate=self.inflate_edges)
        check_endpoint(self.checker, self.link_poses, start, "start")
        if goal is not None:
            check_endpoint(self.checker, self.link_poses, goal, "goal")
        rng = np.random.default_rng(cfg.seed)
        connect_r = 4.0 * cfg.stride if cfg.connect_radius is None else float(cfg.connect_radius)

        # the tree: preallocated, grown in place (numpy on CPU, see module docstring)
        cap = int(cfg.max_nodes)
        nodes = np.empty((cap, d))  # (cap, D)
        parents = np.full(cap, -1, dtype=np.int64)  # (cap,)
        cost = np.zeros(cap)  # path length from the root
        nodes[0] = start
        n = 1
        frozen = hi <= lo
        span = np.where(frozen, 0.0, hi - lo)

        def result(success: bool, path: np.ndarray | None, message: str, it: int) -> PlanResult:
            p = np.zeros((0, d)) if path is None else path
            return PlanResult(
                success=success,
                path=p,
                length=path_length(p) if path is not None else (math.inf if goal is not None else 0.0),
                time_s=time.perf_counter() - t0,
                n_nodes=n,
                n_iters=it,
                tree_nodes=nodes[:n].copy(),
                tree_parents=parents[:n].copy(),
                message=message,
                path_rrt=None if path is None else path.copy(),
                info={"n_queries": edges.n_queries, "edge_resolution": edges.resolution},
            )

        def trace(i: int) -> np.ndarray:
            idx = []
            while i >= 0:
                idx.append(i)
                i = int(parents[i])
            return nodes[idx[::-1]].copy()

        if goal is not None and np.linalg.norm(goal - start) <= connect_r and edges.edges_free(start[None], goal[None])[0]:
            raw = np.stack([start, goal])
            return self._finish(result(True, raw, "direct edge from start to goal is free", 0), edges, t0)

        it = 0
        message = ""
        while True:
            if it >= cfg.max_iters:
                message = f"iteration budget ({cfg.max_iters}) exhausted"
                break
            if n >= cap:
                message = f"node budget ({cap}) exhausted"
                break
            if cfg.time_budget_s is not None and time.perf_counter() - t0 > cfg.time_budget_s:
                message = f"time budget ({cfg.time_budget_s:g} s) exhausted"
                break
            it += 1
            nb = cfg.batch_size
            samples = lo + rng.random((nb, d)) * span  # (N, D)
            if goal is not None and cfg.goal_bias > 0:
                samples[rng.random(nb) < cfg.goal_bias] = goal
            near = np.argmin(cdist(samples, nodes[:n], "sqeuclidean"), axis=1)  # (N,)
            base = nodes[near]  # (N, D)
            delta = samples - base
            dist = np.linalg.norm(delta, axis=1)
            ok = dist > 1e-12
            if not ok.any():
                continue
            base, near, delta, dist = base[ok], near[ok], delta[ok], dist[ok]
            step = np.minimum(dist, cfg.stride) / dist
            new = base + delta * step[:, None]  # steer: at most `stride` towards the sample
            new[:, frozen] = lo[frozen]
            free = edges.edges_free(base, new)  # ONE batched call: (N, n_edge_pts, L)
            if not free.any():
                continue
            k = int(min(free.sum(), cap - n))
            sel = np.nonzero(free)[0][:k]
            ids = np.arange(n, n + k)
            nodes[ids] = new[sel]
            parents[ids] = near[sel]
            cost[ids] = cost[near[sel]] + (dist[sel] * step[sel])
            n += k
            if goal is None:
                continue
            dg = np.linalg.norm(nodes[ids] - goal, axis=1)
            cand = ids[dg <= connect_r]
            if cand.size:
                ok_goal = edges.edges_free(nodes[cand], np.repeat(goal[None], cand.size, axis=0))
                if ok_goal.any():
                    good = cand[ok_goal]
                    best = int(good[np.argmin(cost[good] + np.linalg.norm(nodes[good] - goal, axis=1))])
                    if n < cap:
                        nodes[n] = goal
                        parents[n] = best
                        cost[n] = cost[best] + float(np.linalg.norm(goal - nodes[best]))
                        n += 1
                        raw = trace(n - 1)
                    else:
                        raw = np.vstack([trace(best), goal[None]])
                    return self._finish(result(True, raw, f"goal reached after {it} iterations", it), edges, t0)
            if cfg.goal_tolerance > 0 and np.any(dg <= cfg.goal_tolerance):
                best = int(ids[np.argmin(dg)])
                return self._finish(result(True, trace(best), f"within goal_tolerance after {it} iterations", it), edges, t0)

        if goal is None:
            return result(True, None, f"exploration finished: {message}", it)
        return result(False, None, f"no path found: {message}", it)

    def _finish(self, res: PlanResult, edges: EdgeChecker, t0: float) -> PlanResult:
        if self.config.shortcut and len(res.path) > 2:
            res.path = shortcut_path(edges, res.path)
            res.length = path_length(res.path)
        res.info["n_queries"] = edges.n_queries
        res.time_s = time.perf_counter() - t0
        return res
