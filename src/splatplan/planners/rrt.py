"""Batched RRT (paper Sec. II-E) on the CollisionSplatting checker, in a robot's configuration space.

Each iteration draws ``batch_size`` samples (goal-biased), finds the nearest tree node of every
sample (one vectorised distance matrix), steers from it by at most ``stride``, discretises every
new edge (see *Edge resolution*) and checks all edges together over every robot ellipsoid: a few
batched collision calls, coarse to fine, an edge's checks stopping at its first hit
(``edge_stages``, :class:`EdgeChecker`). Collision-free edges become new nodes.

* **Goal mode** (``goal`` given): new nodes within ``connect_radius`` of the goal try a direct,
  collision-checked edge to the goal (one batched call); the first iteration with a free one ends
  the search and the goal itself becomes the path's last vertex. The path can then be shortcut
  greedily (batched edge checks).
* **Exploration mode** (``goal=None``): grows the tree until the node / iteration / time budget
  and returns it (nodes + parents), e.g. for image-goal retrieval (E6).

**Configuration space.** The robot is a :class:`~splatplan.robots.Robot`: joint space for an arm
(sampled within the joint limits), (x, y, yaw) for a planar base (x, y within the scene's robust
bounds, yaw in [-pi, pi]), R^3 for a sphere or ellipsoid point robot. Distances (stride, goal
tolerance, connect radius) are the weighted Euclidean norm ``|motion_bound * dq|_2`` in scene units
(plain Euclidean distance for a point robot; see :mod:`splatplan.planners.robot_links`).

**Edge resolution (the guarantee).** An edge a -> b is checked at the configurations
``q_k = a + (k / n)(b - a)``, k = 1..n (q_0 = a is already a checked tree node), with
``n = ceil(M(b - a) / edge_resolution)`` and ``M(dq) = sum_j motion_bound_j |dq_j|`` (``|dq|`` for
a translating point robot), which bounds the displacement of every point of every ellipsoid
along the segment. Hence **no point of any robot ellipsoid moves more than ``edge_resolution``
between two consecutive checked configurations**; the default ``edge_resolution`` is
``edge_fraction`` (1/4) of the robot's smallest semi-axis. For a single translating sphere the
inner samples are additionally checked with the radius grown by half the sample spacing (<= r/8
by default): every point of the swept volume lies within that distance of a sample centre, so at
n_sigma = 0 the edge is free between the samples too, not only at them. (Growing every semi-axis
of an anisotropic ellipsoid by m does not contain its Minkowski sum with a ball of radius m, so
this extra test is used for spheres only.)

**Scene-scaled defaults.** Lengths the user leaves unset are derived from the scene and the robot
(:meth:`RRT.settings`): the sampling box is the 0.5-99.5 percentile box of the splat means padded
by the robot's largest semi-axis (joint limits for joints; [-pi, pi] for an unlimited yaw) and
widened to hold the start and goal, which may lie that far beyond the splat means' bounds (a ground
robot's: its footprint diameter, so it can stand beside an object capture), the
stride 1/32 of the largest side of that box in the weighted metric (``(hi - lo) * motion_bound``),
the goal tolerance half the smallest semi-axis, and the search runs until
``time_limit_s`` (default 10 s) rather than a node count. The chosen values are returned in
``PlanResult.info["settings"]``; :meth:`RRTSettings.summary` prints them on one line.

The tree lives in numpy arrays on the CPU, grown in place (doubled when full). That is deliberate:
nearest-neighbour search over it is a (32 x n) distance matrix, and the expensive part (collision
checks) runs on the checker's own device.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import PlanningError
from .bounds import box_margin
from .edges import EdgeChecker, check_endpoint, edge_points, edge_samples, shortcut_path
from .robot_links import LinkGeometry, as_robot
from .rrt_types import PlanResult, RRTConfig, RRTSettings, path_length
from .trees import sq_dists

__all__ = ["RRT", "RRTConfig", "RRTSettings", "PlanResult", "EdgeChecker", "Search", "check_endpoint", "edge_points", "edge_samples",
           "path_length", "robust_scene_box", "shortcut_path", "BOX_PERCENTILE", "STRIDE_FRACTION"]  # fmt: skip

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..robots.robot import Robot

#: percentile of the splat means that bounds the default sampling box on each side (robust to outliers)
BOX_PERCENTILE = 0.5
#: the default stride is this fraction of the largest side of the sampling box
STRIDE_FRACTION = 1.0 / 32.0



def robust_scene_box(scene, percentile: float = BOX_PERCENTILE) -> tuple[np.ndarray, np.ndarray]:
    """(lo (3,), hi (3,)): the [p, 100 - p] percentile box of the splat means (world frame, scene
    units); robust to outlier splats far outside the captured room."""
    m = np.asarray(scene.means)
    lo, hi = np.percentile(m, [percentile, 100.0 - percentile], axis=0)
    return lo.astype(np.float64), hi.astype(np.float64)


@dataclass
class Search:
    """What one search (:meth:`RRT.plan`, :meth:`RRTConnect.plan`) sets up before its first iteration."""

    t0: float  # time.perf_counter() when the call began
    st: RRTSettings
    start: np.ndarray  # (D,)
    goal: np.ndarray | None  # (D,) or None (exploration)
    w: np.ndarray  # (D,) configuration -> metric space (motion bound per coordinate)
    edges: EdgeChecker
    q0: int  # the geometry's query count when the search began
    rng: np.random.Generator
    frozen: np.ndarray  # (D,) bool: coordinates held fixed (lo == hi)
    span: np.ndarray  # (D,) hi - lo (0 where frozen)
    end: float  # time.perf_counter() value the search stops at (inf: none)
    deadline: float | None  # the caller's deadline
    c0: int = 0  # the geometry's configuration count when the search began

    def sample(self, n: int) -> np.ndarray:
        """(n, D) uniform samples of the sampling box."""
        return self.st.box_lo + self.rng.random((n, self.start.size)) * self.span

    def stop(self, config: RRTConfig, it: int, n_nodes: int, info: dict) -> str | None:
        """Why the search stops before iteration ``it + 1`` (None: it goes on); a time-out sets
        ``info["time_limit_hit"]``."""
        if config.max_iters is not None and it >= config.max_iters:
            return f"within the iteration budget ({config.max_iters:,} iterations, {n_nodes:,} nodes)"
        if config.max_nodes is not None and n_nodes >= config.max_nodes:
            return f"within the node budget ({config.max_nodes:,} nodes)"
        if time.perf_counter() > self.end:
            limit = self.st.time_limit_s if self.st.time_limit_s is not None else self.end - self.t0  # the budget the user gave (end: the deadline here)
            info["time_limit_hit"] = True
            return f"within {limit:.1f} s ({n_nodes:,} nodes)"
        return None


class RRT:
    """Batched RRT over a robot's configuration space (see the module docstring).

    Args:
        checker: a :class:`~splatplan.metric.CollisionChecker` (any backend).
        config: :class:`RRTConfig`.
        robot: (required) a :class:`~splatplan.robots.Robot` or a name for
            :func:`~splatplan.robots.load_robot` ("panda", "go2", "sphere:0.015", "ellipsoid:A,B,C",
            a URDF path).
    """

    #: the planner's name in :data:`~splatplan.planners.PLANNERS`
    name = "rrt"
    #: samples per iteration when ``RRTConfig.batch_size`` is None
    default_batch_size = 32

    def __init__(self, checker: CollisionChecker, config: RRTConfig | None = None, *, robot: Robot | str) -> None:
        self.checker = checker
        self.config = (config or RRTConfig()).validate()
        self.geometry = LinkGeometry(as_robot(robot))
        #: a translating sphere: edges are checked between their samples too
        self.inflate_edges = self.geometry.sphere
        #: configurations (their float64 bytes) already found free with this planner's geometry, whose
        #: endpoint check the next search skips (set by :func:`~splatplan.planners.plan` after its
        #: endpoint escapes checked them; used once)
        self._checked_free: set[bytes] = set()

    @property
    def batch_size(self) -> int:
        """Samples per iteration: ``RRTConfig.batch_size``, or this planner's default when None."""
        b = self.config.batch_size
        return self.default_batch_size if b is None else int(b)

    @property
    def robot(self):
        """The :class:`~splatplan.robots.Robot`."""
        return self.geometry.robot

    # ------------------------------------------------------------------ setup
    def _derived_box(self, start: np.ndarray, goal: np.ndarray | None, notes: list[str]) -> tuple[np.ndarray, np.ndarray]:
        """Sampling box from joint limits and the scene's robust bounds (see the module docstring)."""
        geom, d = self.geometry, start.size
        robot = geom.robot
        lim = np.asarray(robot.joint_limits, dtype=np.float64).reshape(d, 2)
        ref = np.asarray(robot.q_default, dtype=np.float64).reshape(d).copy()
        pad = geom.max_semi_axis
        # a ground robot may stand beside the captured space (an object capture ends at the object):
        # its start and goal may lie anywhere within the scene's bounds grown by its footprint diameter
        end_pad = max(pad, box_margin(robot)) if robot.base == "planar" else pad
        lo, hi = lim[:, 0].copy(), lim[:, 1].copy()
        need_scene = [j for j in range(d) if not (np.isfinite(lo[j]) and np.isfinite(hi[j]))]
        if need_scene:  # (an arm within its joint limits needs neither the FK nor the scene box)
            self._scene_box(start, goal, ref, need_scene, lo, hi, pad, end_pad, notes)
        if self.config.frozen:
            for j in self.config.frozen:
                if not 0 <= int(j) < d:
                    raise PlanningError(f"RRTConfig.frozen names coordinate {j}, the configuration has {d}")
                lo[int(j)] = hi[int(j)] = start[int(j)]
        return lo, hi

    def _scene_box(self, start, goal, ref: np.ndarray, need_scene: list[int], lo: np.ndarray, hi: np.ndarray, pad: float, end_pad: float, notes: list[str]) -> None:
        """The box of the coordinates without finite limits (``need_scene``), in place: a translation
        from the scene's robust bounds, an unlimited rotation -pi..pi."""
        robot, d = self.geometry.robot, start.size
        lim = np.asarray(robot.joint_limits, dtype=np.float64).reshape(d, 2)
        c_ref = np.asarray(robot.ellipsoids(ref[None])[0], dtype=np.float64)[0].mean(axis=0)  # (3,) robot centre
        trans_dirs = np.full((d, 3), np.nan)
        for j in np.nonzero(~np.isfinite(lim).all(axis=1))[0].tolist():
            q1 = ref.copy()
            q1[j] += 1.0
            c1, quat1, _ = robot.ellipsoids(np.stack([ref, q1]))
            u = np.asarray(c1[1] - c1[0], dtype=np.float64)  # (E, 3)
            rot_same = quat1 is None or np.allclose(np.abs(np.sum(quat1[0] * quat1[1], axis=-1)), 1.0, atol=1e-9)
            if rot_same and np.allclose(u, u[:1], atol=1e-9) and abs(np.linalg.norm(u[0]) - 1.0) < 1e-6:
                trans_dirs[j] = u[0]
        if need_scene:
            s_lo, s_hi = robust_scene_box(self.checker.scene)
            r_lo, r_hi = self.checker.scene.bounds()
            corners = np.array([[x, y, z] for x in (s_lo[0], s_hi[0]) for y in (s_lo[1], s_hi[1]) for z in (s_lo[2], s_hi[2])])
            raw = np.array([[x, y, z] for x in (r_lo[0], r_hi[0]) for y in (r_lo[1], r_hi[1]) for z in (r_lo[2], r_hi[2])])
            for j in need_scene:
                u = trans_dirs[j]
                if not np.all(np.isfinite(u)):  # an unlimited rotation (e.g. a base's yaw)
                    lo[j], hi[j] = -math.pi, math.pi
                    continue
                off = ref[j] - float(u @ c_ref)  # q_j = off + u . (robot centre)
                lo[j], hi[j] = off + float((corners @ u).min()) - pad, off + float((corners @ u).max()) + pad
                raw_lo, raw_hi = off + float((raw @ u).min()) - end_pad, off + float((raw @ u).max()) + end_pad
                for name, x in (("start", start), ("goal", goal)):
                    if x is None:
                        continue
                    if x[j] < raw_lo - 1e-9 or x[j] > raw_hi + 1e-9:
                        raise PlanningError(
                            f"the {name} {np.array2string(x, precision=4)} lies outside the scene bounds: coordinate {j} = {x[j]:.4g} "
                            f"is not within {raw_lo:.4g}..{raw_hi:.4g} (splat means, padded by the robot size, a ground robot's by its footprint diameter); "
                            f"give a {name} inside the scene or set the sampling box (box_lo/box_hi, --box)"
                        )
                    if x[j] < lo[j] or x[j] > hi[j]:
                        notes.append(f"box widened on coordinate {j} to include the {name} (outside the {BOX_PERCENTILE:g}-{100 - BOX_PERCENTILE:g} percentile box)")
                        lo[j], hi[j] = min(lo[j], x[j]), max(hi[j], x[j])

    def _box(self, start: np.ndarray, goal: np.ndarray | None, notes: list[str]) -> tuple[np.ndarray, np.ndarray]:
        cfg, d = self.config, start.size
        if cfg.box_lo is None or cfg.box_hi is None:
            lo, hi = self._derived_box(start, goal, notes)
            if cfg.box_lo is not None:
                lo = np.asarray(cfg.box_lo, dtype=np.float64).reshape(-1)
            if cfg.box_hi is not None:
                hi = np.asarray(cfg.box_hi, dtype=np.float64).reshape(-1)
        else:
            lo = np.asarray(cfg.box_lo, dtype=np.float64).reshape(-1)
            hi = np.asarray(cfg.box_hi, dtype=np.float64).reshape(-1)
        if lo.shape != (d,) or hi.shape != (d,):
            raise PlanningError(f"the sampling box has dimension {lo.shape}/{hi.shape}, the start has {d}")
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise PlanningError(f"the sampling box must be finite: lo {lo}, hi {hi}")
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
                    f"(joint limits, the given box, or a frozen coordinate lo == hi that must equal the {name}'s)"
                )
        return lo, hi

    def settings(self, start, goal=None) -> RRTSettings:
        """The values a search from ``start`` to ``goal`` will use: the config's where given, else
        derived from the scene and the robot (see the module docstring). Raises like :meth:`plan`."""
        cfg = self.config
        start = np.asarray(start, dtype=np.float64).reshape(-1)
        goal = None if goal is None else np.asarray(goal, dtype=np.float64).reshape(-1)
        self.geometry.bind(start)
        if goal is not None and goal.shape != start.shape:
            raise PlanningError(f"start has {start.size} coordinates but goal has {goal.size}")
        if not np.all(np.isfinite(start)) or (goal is not None and not np.all(np.isfinite(goal))):
            raise PlanningError("start and goal must be finite")
        notes: list[str] = []
        derived: list[str] = []
        lo, hi = self._box(start, goal, notes)
        if cfg.box_lo is None or cfg.box_hi is None:
            derived.append("box")
        geom = self.geometry
        w = geom.distance_scale()
        if cfg.stride is None:
            side = float(np.max((hi - lo) * w)) if np.any(hi > lo) else 1.0
            stride = side * STRIDE_FRACTION
            derived.append("stride")
        else:
            stride = float(cfg.stride)
        if cfg.edge_resolution is None:
            res = cfg.edge_fraction * geom.min_semi_axis
            derived.append("edge_resolution")
        else:
            res = float(cfg.edge_resolution)
        if cfg.goal_tolerance is None:
            tol = 0.5 * geom.min_semi_axis
            derived.append("goal_tolerance")
        else:
            tol = float(cfg.goal_tolerance)
        if not (math.isfinite(stride) and stride > 0 and math.isfinite(res) and res > 0):
            raise PlanningError(f"derived stride {stride} / edge resolution {res} are not usable; set RRTConfig.stride and edge_resolution")
        connect = 4.0 * stride if cfg.connect_radius is None else float(cfg.connect_radius)
        return RRTSettings(lo, hi, stride, res, tol, connect, cfg.time_limit_s, derived, notes)

    def _setup(self, start, goal, deadline: float | None) -> Search:
        """Settings, edge checker, endpoint checks, sampler and deadline of one search (raises like :meth:`plan`)."""
        t0 = time.perf_counter()
        st = self.settings(start, goal)
        start = np.asarray(start, dtype=np.float64).reshape(-1)
        goal = None if goal is None else np.asarray(goal, dtype=np.float64).reshape(-1)
        geom = self.geometry
        edges = EdgeChecker(self.checker, geom, st.edge_resolution, inflate=self.inflate_edges, stages=self.config.edge_stages,
                            slack=self.config.edge_slack, walk=self.config.edge_walk)  # fmt: skip
        q0 = geom.n_queries
        known, self._checked_free = self._checked_free, set()
        if start.tobytes() not in known:
            check_endpoint(self.checker, geom, start, "start")
        if goal is not None and goal.tobytes() not in known:
            check_endpoint(self.checker, geom, goal, "goal")
        frozen = st.box_hi <= st.box_lo
        end = math.inf if deadline is None else float(deadline)
        if st.time_limit_s is not None:
            end = min(end, t0 + st.time_limit_s)
        return Search(t0, st, start, goal, geom.distance_scale(), edges, q0, np.random.default_rng(self.config.seed), frozen,
                       np.where(frozen, 0.0, st.box_hi - st.box_lo), end, deadline, geom.n_configs)  # fmt: skip

    # ------------------------------------------------------------------ search
    def plan(self, start, goal=None, deadline: float | None = None) -> PlanResult:
        """Grow a tree from ``start``; towards ``goal`` (goal mode) or everywhere (goal=None).

        ``deadline`` (a ``time.perf_counter()`` value) ends the search and the shortcut besides
        ``RRTConfig.time_limit_s`` (:func:`~splatplan.planners.plan` shares one budget this way).
        ``info["time_split"]`` gives the seconds spent sampling (and steering), in nearest
        neighbours, in collision checks, shortcutting and the rest.

        Raises:
            PlanningError: start or goal in collision, outside the sampling box / scene bounds /
                joint limits, or a bad box.
        """
        cfg = self.config
        s = self._setup(start, goal, deadline)
        t0, st, start, goal, w, edges, q0, rng = s.t0, s.st, s.start, s.goal, s.w, s.edges, s.q0, s.rng
        d, lo, frozen, geom = start.size, st.box_lo, s.frozen, self.geometry
        connect_r = st.connect_radius

        # the tree: numpy on CPU, grown in place (see module docstring); zs = nodes * w (metric space)
        cap_max = math.inf if cfg.max_nodes is None else int(cfg.max_nodes)
        cap = int(min(cap_max, 4096))
        nodes = np.empty((cap, d))  # (cap, D) configurations
        zs = np.empty((cap, d))  # (cap, D) the same in the weighted metric
        parents = np.full(cap, -1, dtype=np.int64)  # (cap,)
        cost = np.zeros(cap)  # path length from the root (metric)
        nodes[0], zs[0] = start, start * w
        n = 1
        goal_z = None if goal is None else goal * w
        info = {"settings": st.as_dict(), "edge_resolution": st.edge_resolution, "stride": st.stride, "planner": "rrt"}
        clock = {"sampling": 0.0, "nearest": 0.0}

        def result(success: bool, path: np.ndarray | None, message: str, it: int) -> PlanResult:
            p = np.zeros((0, d)) if path is None else path
            return PlanResult(
                success=success,
                path=p,
                length=path_length(p, w) if path is not None else (math.inf if goal is not None else 0.0),
                time_s=time.perf_counter() - t0,
                n_nodes=n,
                n_iters=it,
                tree_nodes=nodes[:n].copy(),
                tree_parents=parents[:n].copy(),
                message=message,
                path_rrt=None if path is None else path.copy(),
                info={**info, "n_queries": geom.n_queries - q0, "n_configs": geom.n_configs - s.c0, "time_split": _split(time.perf_counter() - t0, clock, edges.time_s, 0.0)},
            )

        def trace(i: int) -> np.ndarray:
            idx = []
            while i >= 0:
                idx.append(i)
                i = int(parents[i])
            return nodes[idx[::-1]].copy()

        if goal is not None and np.linalg.norm(goal_z - zs[0]) <= connect_r and edges.edges_free(start[None], goal[None])[0]:
            raw = np.stack([start, goal])
            return self._finish(result(True, raw, "direct edge from start to goal is free", 0), edges, t0, w, q0, clock, deadline, s.c0)

        it = 0
        while (message := s.stop(cfg, it, n, info)) is None:
            it += 1
            nb = self.batch_size
            t1 = time.perf_counter()
            samples = s.sample(nb)  # (N, D)
            if goal is not None and cfg.goal_bias > 0:
                samples[rng.random(nb) < cfg.goal_bias] = goal
            sz = samples * w
            t2 = time.perf_counter()
            near = np.argmin(sq_dists(sz, zs[:n]), axis=1)  # (N,)
            t3 = time.perf_counter()
            clock["sampling"] += t2 - t1
            clock["nearest"] += t3 - t2
            base = nodes[near]  # (N, D)
            delta = samples - base
            dist = np.linalg.norm(sz - zs[near], axis=1)  # metric distance
            ok = dist > 1e-12
            if not ok.any():
                continue
            base, near, delta, dist = base[ok], near[ok], delta[ok], dist[ok]
            step = np.minimum(dist, st.stride) / dist
            new = base + delta * step[:, None]  # steer: at most `stride` towards the sample
            new[:, frozen] = lo[frozen]
            free = edges.edges_free(base, new)  # every edge point and ellipsoid in edge_stages batched calls
            if not free.any():
                continue
            k = int(min(free.sum(), cap_max - n))
            if n + k > cap:  # grow the tree arrays (doubling)
                cap = int(min(cap_max, max(2 * cap, n + k)))
                nodes, zs = _grow(nodes, cap), _grow(zs, cap)
                parents = _grow(parents, cap, fill=-1)
                cost = _grow(cost, cap)
            sel = np.nonzero(free)[0][:k]
            ids = np.arange(n, n + k)
            nodes[ids] = new[sel]
            zs[ids] = new[sel] * w
            parents[ids] = near[sel]
            cost[ids] = cost[near[sel]] + (dist[sel] * step[sel])
            n += k
            if goal is None:
                continue
            dg = np.linalg.norm(zs[ids] - goal_z, axis=1)
            cand = ids[dg <= connect_r]
            if cand.size:
                ok_goal = edges.edges_free(nodes[cand], np.repeat(goal[None], cand.size, axis=0))
                if ok_goal.any():
                    good = cand[ok_goal]
                    best = int(good[np.argmin(cost[good] + np.linalg.norm(zs[good] - goal_z, axis=1))])
                    raw = np.vstack([trace(best), goal[None]])
                    if n < cap:
                        nodes[n], zs[n], parents[n] = goal, goal_z, best
                        cost[n] = cost[best] + float(np.linalg.norm(goal_z - zs[best]))
                        n += 1
                    return self._finish(result(True, raw, f"goal reached after {it} iterations", it), edges, t0, w, q0, clock, deadline, s.c0)
            if st.goal_tolerance > 0 and np.any(dg <= st.goal_tolerance):
                best = int(ids[np.argmin(dg)])
                return self._finish(result(True, trace(best), f"within goal_tolerance after {it} iterations", it), edges, t0, w, q0, clock, deadline, s.c0)

        if goal is None:
            return result(True, None, f"exploration finished: {message}", it)
        return result(False, None, f"no path found {message}", it)

    def _finish(self, res: PlanResult, edges: EdgeChecker, t0: float, w: np.ndarray, q0: int, clock: dict, deadline: float | None, c0: int = 0) -> PlanResult:
        c_search = edges.time_s
        t1 = time.perf_counter()
        if self.config.shortcut and len(res.path) > 2:
            res.path = shortcut_path(edges, res.path, deadline=deadline, screen=self.config.shortcut_screen)
            res.length = path_length(res.path, w)
        res.info["n_queries"] = edges.n_queries - q0
        res.info["n_configs"] = edges.n_configs - c0
        res.time_s = time.perf_counter() - t0
        res.info["time_split"] = _split(res.time_s, clock, c_search, time.perf_counter() - t1)
        return res


def _split(total: float, clock: dict, collision: float, shortcut: float) -> dict:
    """The time split of a search: sampling, nearest, collision, shortcut, other (= the rest) seconds."""
    out = {"sampling": clock["sampling"], "nearest": clock["nearest"], "collision": collision, "shortcut": shortcut}
    out["other"] = max(0.0, total - sum(out.values()))
    return out


def _grow(a: np.ndarray, cap: int, fill=0) -> np.ndarray:
    out = np.full((cap,) + a.shape[1:], fill, dtype=a.dtype)
    out[: len(a)] = a
    return out
