"""Quadruped base driving under MPPI (paper Sec. IV, E6's last stage): the Go2 to a goal position
given **only the goal** (e.g. the final node of an RRT path), around obstacles and through
doorways on the collision cost alone.

State (x, y, yaw) of the base in the world (metres, radians); controls (vx, vy, wz) in the body
frame, a cubic B-spline over the horizon, clipped to the robot's velocity limits
(:class:`~splatplan.planners.dynamics.PlanarBase`). Every body and leg ellipsoid of the Go2 at its
standing height enters the collision cost (one ``query_robot`` per MPC step on the (K, T, 3)
batch, every step of the horizon: with a stride of 2 the base grazed a door post, -3.6 cm exact).
Goal cost per rollout: ``w_goal (sum_t d_t + terminal_factor d_T + min_factor min_t d_t)`` with d
the distance of the base to the goal, plus ``w_heading`` for facing the goal and a small yaw-rate
cost (without them the heading drifts, and the 0.7 m long body meets a doorway sideways).

The planner (:class:`_BasePlanner`, MPPI over the same B-spline knots as
:class:`~splatplan.planners.MPPI`, with its own sampling) adds three local-planner techniques, all
from the goal and the collision checks near the base only (no prior map, no route):

* **Structured samples**: next to the Gaussian knot perturbations of the nominal, straight drives
  in ``n_directions`` world directions and the same drives switching to the bearing to the goal
  after 1/4, 1/2 and 3/4 of the horizon (knots fitted by ridge least squares), all turning the base towards their direction of travel
  (``primitive_turn_rate``). They let MPPI see "along the wall, then through the doorway".
* **Stagnation recovery** (``recovery``): when the distance to the goal has not improved by
  ``stuck_progress_m`` for ``stuck_steps`` steps (and the base is more than
  ``recovery_min_distance_m`` from the goal), the base sidesteps: it sweeps perpendicular to the
  bearing to the goal, first to the side ``first_sweep`` (clockwise by default, a fixed convention
  like the Bug algorithms' turning direction; the other side where an earlier sweep started
  within 0.5 m), facing its direction of travel (``w_align``), and reverses with twice the length
  when blocked or after ``detour_length_m`` (a doubling search). The sweep's cost is progress
  along its direction (``w_sweep``) plus the collision cost. It ends as soon as a collision-free
  rollout gets ``detour_exit_margin_m`` closer to the goal than the base ever was and than any
  collision-free rollout of goal mode ever got; the nominal then becomes that rollout. Every
  sweep, reversal and resume is recorded in ``extra["events"]``. **Off by default**: in the base
  study it reached no goal that plain MPPI missed (3/5 either way; the kitchen goals fail both
  ways), and it can fire while the base is still lining up with a doorway (bedroom goal
  (1.12, 1.81), seeds 0-5: 5/6 reached with it, 6/6 without).
* **Sensed-obstacle memory** (``memory``, off by default; :class:`ObstacleMemory`): how
  navigation stacks get out of local minima with no prior map (the freespace assumption of D*
  Lite in unknown terrain). The base keeps a coarse occupancy grid (``memory_cell_m``) of the
  scene box, *unknown = free* at the start; every MPC step it senses the cells within
  ``sensor_radius_m`` that it has not sensed before and that are in its line of sight
  (``sensor_occlusion``, on by default: like a 2D lidar at ``sensor_height_m``, the segment to the
  cell is free of scene surfaces by the metric up to one cell before the cell's centre; cells out
  of sight stay unknown and are tried again every step) (blocked: the Go2 collides there at every
  one of ``memory_yaws`` headings; batched ``collides_robot`` calls, memoised). The goal terms d_t
  above then read the **geodesic** distance to the goal on that grid (8-connected Dijkstra over
  the not-blocked cells, recomputed only when new cells are blocked, bilinear between cell
  centres) with an inflation layer (``memory_inflation_m``, ``memory_inflation_cost``: cells
  near blocked ones cost more, so the geodesic keeps to the middle of passages and doorways;
  without it the base hugged the door post of the kitchen doorway, every sample collided, and it
  backed out); the heading term faces the field's descent, and the structured drives switch to
  following that descent (streamlines) instead of the bearing to the goal, plus two pure
  followers. The collision cost is unchanged: the field only shapes the goal cost. The sensor
  sees nothing beyond its radius nor behind a surface; no map of the scene is built before
  driving. In the base study it reaches the two kitchen goals that plain MPPI misses (5/5 against
  3/5; with the line of sight as without it, in 21-24 s against 16-17 s: the base learns less of
  the wall ahead of time).

**Conservatism.** The base runs the metric at ``n_sigma = 0.75``: at n_sigma = 1 the splats'
inflation (about 0.13 m per side on the walls) leaves **no** collision-free pose of the Go2 (yaw 0)
in the 0.8 m living-kitchen doorway and a 6 cm band (at yaw 90 deg) in the 0.8 m bedroom-kitchen
one, so the kitchen is unreachable; at 0.75 the free bands of the centre are 16, 28 and 20 cm
(living-kitchen, living-bedroom, bedroom-kitchen). At 0.5 (31, 38, 34 cm) the base grazed the
exact boxes by 2-3 cm in tight spots, which the metric at 0.5 did not see. The exact clearance
to the boxes is what the studies report.

With ``route`` (a path, e.g. from :func:`plan_route`), the goal cost follows the route instead
(:class:`RouteTracker`: the point ``route_lookahead_m`` ahead of the base's progress along it,
and the heading term faces the route's yaw there, the heading the RRT found free) and the recovery
and the memory are off (``--route`` in the CLI, and by default there when the straight line to the
goal is blocked).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .._config import bounded, check_config
from .._resources import require_rollouts
from ..errors import SplatplanError
from ._common import TaskResult, base_terrain, check_start, load_task_scene, trajectory_clearance
from .memory import ObstacleMemory, _geodesic_field_reference, _line_of_sight_reference, geodesic_field, line_of_sight  # noqa: F401  (re-exported)

__all__ = ["FOOT_CLEARANCE", "START", "BaseConfig", "ObstacleMemory", "RouteTracker", "safe_step", "geodesic_field", "line_of_sight", "load_go2", "plan_route", "run_base"]

#: The Go2's feet ellipsoids are lifted this far (m) above the floor (as in a trot's swing phase), so
#: the floor itself is not a collision.
FOOT_CLEARANCE = 0.04
#: Default start (x, y, yaw) of the base in the built-in ``apartment``: the living room, the base
#: study's start (the origin lies in the x = 0 wall).
START = (-2.3, -0.6, 0.0)


def load_go2():
    """The Go2 (planar base x, y, yaw) raised by :data:`FOOT_CLEARANCE` above its standing height."""
    from ..robots import load_robot

    r = load_robot("go2")
    pose = r.base_pose.copy()
    pose[2, 3] += FOOT_CLEARANCE
    robot = load_robot("go2", base_pose=pose)
    robot.info["standing_height_m"] = float(pose[2, 3])
    return robot


@dataclass
class BaseConfig:
    """Knobs of :func:`run_base` (MPPI over body-frame velocity B-splines)."""

    #: sampled control sequences K per MPPI iteration
    n_samples: int = bounded(64, ge=2)
    #: horizon T (control steps)
    horizon: int = bounded(20, ge=2)
    #: B-spline knots per control over the horizon
    n_knots: int = bounded(6, ge=4)
    #: control period (s)
    dt: float = bounded(0.2, gt=0)
    #: MPPI temperature
    temperature: float = bounded(0.5, gt=0)
    #: knot noise std (vx m/s, vy m/s, wz rad/s)
    noise_sigma: tuple[float, float, float] = bounded((0.6, 0.4, 0.3), ge=0)
    #: maximum MPC steps
    max_steps: int = bounded(250, ge=1)
    #: weight of the distance to the goal (per metre, per step)
    w_goal: float = bounded(1.0, ge=0)
    #: extra weight of the last step of the goal cost
    terminal_factor: float = bounded(5.0, ge=0)
    #: weight of the smallest distance to the goal along each rollout (min over t; a rollout that
    #: passes close to the goal, e.g. through a doorway and on, is preferred)
    min_factor: float = bounded(5.0, ge=0)
    #: structured samples: straight drives in this many world directions (one is the bearing to
    #: the goal) and the same drives turning to the goal after 1/4, 1/2, 3/4 of the horizon (0 = off)
    n_directions: int = bounded(8, ge=0)
    #: speed of the structured samples (m/s)
    primitive_speed: float = bounded(0.8, ge=0)
    #: turn rate (rad/s) of the structured samples towards their direction of travel
    primitive_turn_rate: float = bounded(1.5, ge=0)
    #: stagnation recovery: when the distance to the goal has not improved for stuck_steps,
    #: sidestep perpendicular to the bearing to the goal, back and forth with doubling sweeps,
    #: until a collision-free rollout gets clearly closer to the goal than ever before (off by
    #: default: see the module docstring)
    recovery: bool = False
    #: MPC steps without progress that count as stagnation (goal) or a blocked sweep
    stuck_steps: int = bounded(10, ge=1)
    #: no recovery closer than this to the goal (m): the final approach is slow, not stuck
    recovery_min_distance_m: float = bounded(0.5, ge=0)
    #: progress (m) that resets the stagnation counter
    stuck_progress_m: float = bounded(0.05, ge=0)
    #: length (m) of the first sweep; each reversal sweeps back twice as far
    detour_length_m: float = bounded(2.0, gt=0)
    #: a detour ends when a collision-free rollout gets this much closer (m) to the goal than the
    #: base ever was or any collision-free rollout of goal mode saw before the detour
    detour_exit_margin_m: float = bounded(0.3, ge=0)
    #: side of the first sweep: -1 clockwise (right of the bearing to the goal), +1 counterclockwise
    #: (a fixed convention, like the Bug algorithms' turning direction)
    first_sweep: int = bounded(-1, choices=(-1, 1))
    #: sweeps: weight of the progress along the sweep direction (per metre, per step)
    w_sweep: float = bounded(0.3, ge=0)
    #: sweeps: weight of facing the sweep direction sum_t (1 - cos(yaw_t - heading)) (walk forward)
    w_align: float = bounded(1.0, ge=0)
    #: weight of the yaw rate sum_t wz^2 dt (keeps the heading from drifting; the base walks
    #: sideways when it has to)
    w_yaw_rate: float = bounded(0.1, ge=0)
    #: weight of facing the goal: sum_t (1 - cos(yaw_t - bearing to the goal)) (a walking robot
    #: moves best forward; 0 = off)
    w_heading: float = bounded(0.5, ge=0)
    #: weight of the summed CollisionSplatting cost
    w_collision: float = bounded(2.0, ge=0)
    #: cost per (step, ellipsoid) in collision (kept small: a large one makes every sample that
    #: grazes a door post lose to standing still, and the base never threads a doorway)
    w_hit: float = bounded(10.0, ge=0)
    #: weight of the control effort
    w_control: float = bounded(0.02, ge=0)
    #: conservatism of the metric (n_sigma)
    n_sigma: float = bounded(0.75, ge=0)
    #: neighbourhood of the rollouts' collision cost (checker s2_cap for MPPI queries)
    collision_s2_cap: float = bounded(2.0, ge=1)
    #: query the collision cost on every stride-th step of the horizon
    collision_stride: int = bounded(1, ge=1)
    #: with a route: the goal term tracks the route's point this far (m, arc length) ahead of the
    #: base's progress along it, and the heading term its heading there (the route's yaw is one the
    #: RRT found free: in a narrow passage only a few headings are)
    route_lookahead_m: float = bounded(0.4, gt=0)
    #: check each executed control period's motion (densified to 1 cm of ellipsoid motion, as the
    #: reported clearance is) before driving it; a colliding one is halved (twice), else the base holds
    #: still for that period. The rollouts are checked only at their 0.2 s steps, so at speed a
    #: thin obstacle (a leg's 4 cm against 16 cm a step) can fall between two of them
    safe_step: bool = True
    #: success: final distance to the goal below this (m)
    goal_tol: float = bounded(0.2, gt=0)
    #: height of the floor (m; 0 after `scene align`), auto = fitted from the scene, none = no terrain:
    #: floor-like splats below ground_z + ground_band are terrain, not obstacles (scenes/terrain.py)
    ground_z: float | str | None = 0.0
    #: the base's step height above the floor (m): the terrain band (an obstacle lower than this is missed)
    ground_band: float = bounded(0.05, ge=0)
    #: sensed-obstacle memory (off by default): a coarse occupancy grid, unknown = free, filled with
    #: the cells sensed within sensor_radius_m of the base every MPC step; the goal cost then uses
    #: the geodesic distance to the goal on it instead of the straight line (see ObstacleMemory)
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
    #: noise seed
    seed: int = bounded(0, ge=0)

    def validate(self) -> "BaseConfig":
        """Check every field's declared range (:mod:`splatplan._config`) and the cross-field rules; returns self."""
        check_config(self)
        require_rollouts(self.n_samples, self.horizon, "BaseConfig")
        if self.n_knots > self.horizon:
            raise SplatplanError(f"BaseConfig.n_knots must be <= horizon (knots of a spline over the horizon's steps), got n_knots={self.n_knots}, horizon={self.horizon}")
        return self



def plan_route(
    robot, checker, start, goal_xy, time_budget_s: float = 60.0, seed: int = 0, edge_resolution: float = 0.05, stride: float = 0.4, goal_bias: float = 0.2
) -> np.ndarray | None:
    """Global route on the base's SE(2) with the batched RRT: (P, 3) configurations (x, y, yaw),
    or None when none is found within ``time_budget_s``.

    The goal's yaw is free: the RRT goal is the goal position at the collision-free heading nearest
    to the bearing from the start. The route is a guide that MPPI tracks with its own collision
    cost (the executed motion is what the clearance measures), so its edges are checked every
    ``edge_resolution`` = 5 cm (half a wall's thickness) of ellipsoid motion rather than at the
    RRT default of a quarter of the Go2's smallest semi-axis (a 1.9 cm foot: 4.8 mm, ~80 checks
    per edge, which is why the default search did not reach the kitchen in 30 s), with a
    ``stride`` of 0.4 m and a goal bias of 0.2."""
    from ..planners import RRT, RRTConfig

    start = np.asarray(start, np.float64)
    g = np.asarray(goal_xy, np.float64)
    bearing = float(np.arctan2(g[1] - start[1], g[0] - start[0]))
    yaws = bearing + np.linspace(-np.pi, np.pi, 24, endpoint=False)
    yaws = yaws[np.argsort(np.abs(np.angle(np.exp(1j * (yaws - bearing)))))]  # nearest to the bearing first
    q = np.stack([np.full(len(yaws), g[0]), np.full(len(yaws), g[1]), np.angle(np.exp(1j * yaws))], axis=1)
    free = ~np.asarray(checker.collides_robot(robot, q)).any(axis=-1)
    if not free.any():
        raise SplatplanError(f"goal {g.round(3).tolist()}: the base collides there at every heading; pick a free goal")
    yaw = float(q[np.argmax(free), 2])
    lo, hi = checker.scene.bounds()
    cfg = RRTConfig(box_lo=(float(lo[0]), float(lo[1]), -np.pi), box_hi=(float(hi[0]), float(hi[1]), np.pi), time_limit_s=time_budget_s, seed=seed, goal_tolerance=0.1,
                    edge_resolution=edge_resolution, stride=stride, goal_bias=goal_bias)  # fmt: skip
    res = RRT(checker, cfg, robot=robot).plan(start, np.array([g[0], g[1], yaw]))
    if not res.success:
        return None
    return np.asarray(res.path)


class RouteTracker:
    """Where the base heads along a route: the point ``lookahead`` (m of arc length) ahead of its
    progress, and the route's yaw there. Progress is the nearest point of the route (resampled every
    2 cm) within ``2 lookahead`` past the last progress and never goes back, so a route that
    doubles back on itself is followed in order."""

    def __init__(self, route: np.ndarray, lookahead: float, step: float = 0.02) -> None:
        r = np.asarray(route, np.float64)  # (P, 2) or (P, 3) x, y[, yaw]
        if r.ndim != 2 or r.shape[1] < 2 or len(r) < 1:
            raise SplatplanError(f"a route must be (P, 2) or (P, 3) waypoints, got shape {r.shape}")
        yawed = r.shape[1] >= 3  # else each segment faces along itself
        r = np.c_[r[:, :2], np.unwrap(r[:, 2]) if yawed else np.zeros(len(r))]
        pts = [r[:1]]
        for a, b in zip(r[:-1], r[1:]):
            if not yawed:
                a, b = a.copy(), b.copy()
                a[2] = b[2] = np.arctan2(b[1] - a[1], b[0] - a[0])
            n = max(1, int(np.ceil(np.linalg.norm(b[:2] - a[:2]) / step)))
            pts.append(a + (b - a) * (np.arange(1, n + 1)[:, None] / n))
        if not yawed and len(pts) > 1:
            pts[0] = pts[0].copy()
            pts[0][0, 2] = pts[1][0, 2]
        self.dense = np.concatenate(pts)  # (M, 3) x, y, yaw (unwrapped)
        self.arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(self.dense[:, :2], axis=0), axis=1))]  # (M,) m
        self.lookahead = float(lookahead)
        self.s = 0.0  # progress (m of arc length)

    def target(self, xy: np.ndarray) -> tuple[np.ndarray, float]:
        """(target xy (2,), route yaw there) for the base at ``xy``; advances the progress."""
        win = np.flatnonzero((self.arc >= self.s) & (self.arc <= self.s + 2.0 * self.lookahead))
        i = int(win[np.argmin(np.linalg.norm(self.dense[win, :2] - xy, axis=1))])
        self.s = float(self.arc[i])
        j = min(int(np.searchsorted(self.arc, self.s + self.lookahead)), len(self.arc) - 1)
        return self.dense[j, :2].copy(), float(self.dense[j, 2])


def safe_step(robot, checker, dyn, x: np.ndarray, u: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray | None]:
    """(control, next state) of the first of ``u``, ``u / 2``, ``u / 4`` whose motion over one period
    ``dt`` from ``x`` is free by the metric at every configuration of :func:`densify` (the reported
    clearance's sampling); (0, None) when all collide: the caller holds the base still."""
    from ._common import densify

    for f in (1.0, 0.5, 0.25):
        uf = u * f
        x1 = dyn.rollout(x, uf[None, None, :], dt)[0, 0]
        q = densify(robot, np.stack([x, x1]))
        if not np.asarray(checker.collides_robot(robot, q)).any():
            return uf, x1
    return np.zeros_like(u), None


def _free_yaw(robot, checker, xy) -> float | None:
    """A yaw at which the base at ``xy`` is collision-free (None if every one of 16 collides)."""
    yaws = np.linspace(-np.pi, np.pi, 16, endpoint=False)
    q = np.stack([np.full(16, xy[0]), np.full(16, xy[1]), yaws], axis=1)
    free = ~np.asarray(checker.collides_robot(robot, q)).any(axis=-1)
    return float(yaws[np.argmax(free)]) if free.any() else None


class _BasePlanner:
    """MPPI over body-frame velocity B-splines for the planar base, with structured samples and a
    stagnation recovery (see the module docstring). One :meth:`step` per control period."""

    def __init__(self, dyn, cfg: BaseConfig, vmax: np.ndarray, collision_cost, goal: np.ndarray, recovery: bool = True, memory: ObstacleMemory | None = None) -> None:
        from ..planners.bspline import UniformBSpline

        self.dyn, self.cfg, self.vmax = dyn, cfg, np.asarray(vmax, np.float64)
        self.collision = collision_cost
        self.spline = UniformBSpline(cfg.n_knots, cfg.horizon, clamped=False)  # see tasks.arm
        bb = self.spline.basis  # (T, n_knots); ridge: the unclamped first / last knots barely act, unregularised they blow up
        self._basis_pinv = np.linalg.solve(bb.T @ bb + 0.1 * np.eye(cfg.n_knots), bb.T)  # (n_knots, T): controls -> knots
        self.sigma = np.asarray(cfg.noise_sigma, np.float64).reshape(3)
        self.rng = np.random.default_rng(cfg.seed)
        self.knots = np.zeros((cfg.n_knots, 3))  # (n_knots, 3) nominal body-frame (vx, vy, wz)
        self.goal = np.asarray(goal, np.float64)
        self.recovery = bool(recovery)
        self.memory = memory  # ObstacleMemory: geodesic goal distance and heading (None: straight line)
        self.heading_ref: float | None = None  # route tracking: the yaw to face (rad), instead of the bearing to the goal
        self.mode = "goal"
        self.best = np.inf  # best distance to the goal reached so far (m)
        self.best_step = 0
        self.step_i = 0
        self.detour: dict | None = None
        self.events: list[dict] = []
        self.seen = np.inf  # closest approach to the goal of the last goal-mode step's collision-free rollouts (m)

    # ---------------------------------------------------------------- samples
    def _clip(self, knots: np.ndarray) -> np.ndarray:
        return np.clip(knots, -self.vmax, self.vmax)

    def _drive_knots(self, x: np.ndarray, v_world: np.ndarray) -> np.ndarray:
        """(P, T, 2) world-frame velocities per control step -> (P, n_knots, 3) body-frame knots
        (least-squares fit of the controls) that also turn the base towards its direction of
        travel (tracking a route: towards the route's heading) at up to ``primitive_turn_rate``."""
        cfg = self.cfg
        p, t_len, _ = v_world.shape
        u = np.zeros((p, t_len, 3))
        yaw = np.full(p, float(x[2]))
        for t in range(t_len):
            psi = np.arctan2(v_world[:, t, 1], v_world[:, t, 0]) if self.heading_ref is None else np.full(p, self.heading_ref)  # route: its heading
            wz = np.clip(np.angle(np.exp(1j * (psi - yaw))) / cfg.dt, -cfg.primitive_turn_rate, cfg.primitive_turn_rate)
            wz = np.where(np.hypot(v_world[:, t, 0], v_world[:, t, 1]) > 1e-9, wz, 0.0)  # stopped: keep the heading
            c, s_ = np.cos(yaw), np.sin(yaw)
            u[:, t, 0] = c * v_world[:, t, 0] + s_ * v_world[:, t, 1]
            u[:, t, 1] = -s_ * v_world[:, t, 0] + c * v_world[:, t, 1]
            u[:, t, 2] = wz
            yaw = yaw + wz * cfg.dt
        return np.einsum("nt,ptd->pnd", self._basis_pinv, u)

    def primitives(self, x: np.ndarray) -> np.ndarray:
        """(P, n_knots, 3) structured samples: straight drives in ``n_directions`` world
        directions (one is the bearing to the target: the goal, or the sweep's direction), and
        the same drives switching to the bearing to the target (from the predicted switch point)
        after 1/4, 1/2 and 3/4 of the horizon; all turn the base towards their direction of travel."""
        cfg = self.cfg
        m, t_len = cfg.n_directions, cfg.horizon
        if m <= 0:
            return np.zeros((0, cfg.n_knots, 3))
        tgt = self.goal
        if self.mode == "detour":
            tgt = x[:2] + 10.0 * np.array([np.cos(self.detour["heading"]), np.sin(self.detour["heading"])])
        geo = self.memory is not None and self.mode == "goal"  # the target's direction: descent of the memory's field
        b = float(self.memory.heading(x[:2])) if geo else float(np.arctan2(tgt[1] - x[1], tgt[0] - x[0]))
        th = b + 2 * np.pi * np.arange(m) / m  # (m,)
        v = cfg.primitive_speed * np.stack([np.cos(th), np.sin(th)], axis=1)  # (m, 2) world, m/s
        vw = [np.repeat(v[:, None], t_len, axis=1)]  # straight
        if geo:  # the same drives following the field's descent from their switch points, and two pure followers
            return self._drive_knots(x, np.concatenate(vw + self._followers(x, v, t_len)))
        vw[0][0] = self._to_target(x[:2], tgt, 0, vw[0][:1])[0]  # the drive along the bearing stops at the target
        for frac in (0.25, 0.5, 0.75):
            j = max(1, int(round(frac * t_len)))
            k = np.repeat(v[:, None], t_len, axis=1)
            vw.append(self._to_target(x[:2], tgt, j, k))
        return self._drive_knots(x, np.concatenate(vw))

    def _to_target(self, xy: np.ndarray, tgt: np.ndarray, j: int, vel: np.ndarray) -> np.ndarray:
        """(P, T, 2) world velocities ``vel`` whose steps from ``j`` on are replaced by a drive to
        ``tgt`` that **stops at it**: a drive that overshot the goal would run into the far wall of
        a small room within the horizon and lose to standing still. The speed is
        ``primitive_speed``, or less where the target is nearer than that covers in half the
        remaining horizon (a short drive stretched over several steps: the knots' B-spline cannot
        hold a one-step pulse)."""
        cfg = self.cfg
        out = vel.copy()
        p = xy + out[:, :j].sum(axis=1) * cfg.dt  # (P, 2) world, the switch points
        half = max(1, (out.shape[1] - j) // 2) * cfg.dt  # s
        speed = np.minimum(cfg.primitive_speed, np.linalg.norm(tgt - p, axis=1, keepdims=True) / half)  # (P, 1) m/s
        for t in range(j, out.shape[1]):
            d = tgt - p  # (P, 2)
            n = np.linalg.norm(d, axis=1, keepdims=True)
            out[:, t] = d / np.maximum(n, 1e-9) * np.minimum(speed, n / cfg.dt)
            p = p + out[:, t] * cfg.dt
        return out

    def _followers(self, x: np.ndarray, v: np.ndarray, t_len: int) -> list[np.ndarray]:
        """Memory mode: (m, T, 2) world velocities of the drives ``v`` (m, 2) switching after 1/4,
        1/2, 3/4 of the horizon to following the descent of the geodesic field (a streamline
        integrated from the predicted switch point), and (2, T, 2) pure followers at full and half
        ``primitive_speed``."""
        cfg = self.cfg
        out = []
        for frac in (0.25, 0.5, 0.75, 0.0):
            j = int(round(frac * t_len))
            vel = np.repeat(v[:, None], t_len, axis=1) if j else np.zeros((2, t_len, 2))  # (P, T, 2) world, m/s
            speed = np.full((len(vel), 1), cfg.primitive_speed) if j else cfg.primitive_speed * np.array([[1.0], [0.5]])  # (P, 1) m/s
            p = x[:2] + vel[:, 0] * j * cfg.dt  # (P, 2) world, the switch points
            for t in range(j, t_len):
                h = self.memory.heading(p)
                vel[:, t] = speed * np.stack([np.cos(h), np.sin(h)], axis=1)
                p = p + vel[:, t] * cfg.dt
            out.append(vel)
        return out

    # ---------------------------------------------------------------- costs
    def evaluate(self, x: np.ndarray, knots: np.ndarray) -> dict:
        """Roll out and cost (K, n_knots, 3) knots: states (K, T, 3), per-step goal distances
        (K, T), goal-mode cost, collision cost and in-collision flags (K,)."""
        from ..planners.costs import Rollout

        cfg = self.cfg
        controls = self.spline(knots)  # (K, T, 3) body frame
        states = self.dyn.rollout(x, controls, cfg.dt)  # (K, T, 3) world
        ro = Rollout(states, controls, cfg.dt)
        k = len(knots)
        col = np.zeros(k)
        hit = np.zeros(k, bool)  # (K,) any ellipsoid in collision at any checked step
        if self.collision is not None:
            terms = self.collision.terms(ro)
            col = np.sum(list(terms.values()), axis=0)
            q = ro.cache["query"]  # (K, T', E) over the evaluated steps
            hit = np.asarray(q.in_collision).reshape(k, -1).any(axis=1)
        ctrl = cfg.w_control * np.sum(controls**2, axis=(1, 2)) * cfg.dt + cfg.w_yaw_rate * np.sum(controls[..., 2] ** 2, axis=1) * cfg.dt
        dist = np.linalg.norm(states[..., :2] - self.goal, axis=-1)  # (K, T) m, straight line
        gd = dist if self.memory is None else self.memory.distance(states[..., :2])  # (K, T) m, geodesic on the memory
        goal = cfg.w_goal * (gd.sum(axis=1) + cfg.terminal_factor * gd[:, -1] + cfg.min_factor * gd.min(axis=1))
        if cfg.w_heading > 0 and self.heading_ref is not None:  # route tracking: the route's heading, all the way
            goal = goal + cfg.w_heading * (1.0 - np.cos(states[..., 2] - self.heading_ref)).sum(axis=1)
        elif cfg.w_heading > 0:
            if self.memory is None:
                bearing = np.arctan2(self.goal[1] - states[..., 1], self.goal[0] - states[..., 0])
            else:  # face along the geodesic
                bearing = self.memory.heading(states[..., :2])
            goal = goal + cfg.w_heading * np.where(dist < 0.3, 0.0, 1.0 - np.cos(states[..., 2] - bearing)).sum(axis=1)
        return {"states": states, "dist": dist, "goal": goal, "collision": col, "control": ctrl, "hit": hit}

    # ---------------------------------------------------------------- recovery
    def _start_detour(self, x: np.ndarray) -> None:
        """Stagnation: sidestep, perpendicular to the bearing to the goal, first to the side
        ``first_sweep`` (the other side where an earlier sweep started within 0.5 m: that one did
        not lead out), reversing with doubled length when blocked or done."""
        cfg = self.cfg
        bearing = float(np.arctan2(self.goal[1] - x[1], self.goal[0] - x[0]))
        side = float(np.sign(cfg.first_sweep) or 1.0)
        for e in self.events:
            if e["event"] == "detour" and np.linalg.norm(np.asarray(e["xy"]) - x[:2]) < 0.5:
                side = -e["side_sign"]
        self.detour = {"ref": min(self.best, self.seen), "side": side, "heading": bearing + side * np.pi / 2, "limit": cfg.detour_length_m, "walked": 0.0, "last": x[:2].copy(), "window": [x[:2].copy()]}
        self.mode = "detour"
        self.events.append({"step": self.step_i, "event": "detour", "xy": x[:2].round(3).tolist(), "side": "counterclockwise" if side > 0 else "clockwise", "side_sign": side, "distance_m": round(float(self.best), 3)})

    # ---------------------------------------------------------------- step
    def step(self, x: np.ndarray) -> np.ndarray:
        """One control period from (x, y, yaw): returns the body-frame command (vx, vy, wz)."""
        from ..planners.mppi import mppi_weights

        cfg = self.cfg
        if self.memory is not None:
            self.memory.sense(x[:2])
        dist_now = float(np.linalg.norm(x[:2] - self.goal))
        if dist_now < self.best - cfg.stuck_progress_m:
            self.best, self.best_step = dist_now, self.step_i
        if self.recovery and self.mode == "goal" and self.step_i - self.best_step >= cfg.stuck_steps and dist_now > cfg.recovery_min_distance_m:
            self._start_detour(x)
        if self.mode == "detour":
            det = self.detour
            det["walked"] += float(np.linalg.norm(x[:2] - det["last"]))
            det["last"] = x[:2].copy()
            det["window"] = (det["window"] + [x[:2].copy()])[-cfg.stuck_steps :]
            blocked = len(det["window"]) == cfg.stuck_steps and np.linalg.norm(det["window"][-1] - det["window"][0]) < 2 * cfg.stuck_progress_m
            if blocked or det["walked"] >= det["limit"]:  # sweep back the other way, twice as far
                det["heading"] += np.pi
                det["side"] = -det["side"]
                det["limit"] = 2.0 * det["limit"] + det["walked"]
                det["walked"], det["window"] = 0.0, [x[:2].copy()]
                self.events.append({"step": self.step_i, "event": "reverse", "xy": x[:2].round(3).tolist()})
        prim = self.primitives(x)
        k_rand = max(cfg.n_samples - len(prim), 1)
        eps = self.rng.standard_normal((k_rand, cfg.n_knots, 3)) * self.sigma
        eps[0] = 0.0  # the nominal itself
        samples = self._clip(np.concatenate([prim, self.knots[None] + eps]))  # (K, n, 3)
        ev = self.evaluate(x, samples)
        base = ev["collision"] + ev["control"]
        resumed = False
        if self.mode == "detour":
            # leave the detour when a collision-free rollout gets clearly closer than ever before
            ok = (~ev["hit"]) & (ev["dist"].min(axis=1) < self.detour["ref"] - cfg.detour_exit_margin_m)
            if ok.any():
                i = int(np.flatnonzero(ok)[np.argmin((base + ev["goal"])[ok])])
                self.events.append({"step": self.step_i, "event": "resume", "xy": x[:2].round(3).tolist(), "rollout_distance_m": round(float(ev["dist"][i].min()), 3)})
                self.mode, self.detour = "goal", None
                self.best_step = self.step_i
                self.knots = samples[i].copy()
                resumed = True
        if self.mode == "goal":  # what goal mode can see: the closest approach of a collision-free rollout
            free_d = ev["dist"].min(axis=1)[~ev["hit"]]
            self.seen = min(self.seen, float(free_d.min()) if free_d.size else np.inf)  # over every goal-mode step
        if not resumed:
            if self.mode == "detour":
                d = np.array([np.cos(self.detour["heading"]), np.sin(self.detour["heading"])])
                prog = (ev["states"][..., :2] - x[:2]) @ d  # (K, T) m along the followed heading
                align = (1.0 - np.cos(ev["states"][..., 2] - self.detour["heading"])).sum(axis=1)  # walk forward
                total = base - cfg.w_sweep * prog.sum(axis=1) + cfg.w_align * align
            else:
                total = base + ev["goal"]
            self.knots = self._clip(np.einsum("k,knd->nd", mppi_weights(total, cfg.temperature), samples))
        u0 = self.spline(self.knots[None])[0, 0].copy()
        self.knots = self._clip(self.spline.shift(self.knots))  # warm start: shift by one period
        self.step_i += 1
        return u0


def run_base(
    robot,
    scene,
    goal_xy,
    *,
    start=None,
    config: BaseConfig | None = None,
    collision: bool = True,
    route: np.ndarray | None = None,
    device: str | None = "cpu",
    progress=None,
) -> TaskResult:
    """Drive the base to ``goal_xy`` with MPPI (see the module docstring).

    Args:
        robot: a planar-base Robot (default Go2 from :func:`load_go2`), or None.
        scene: a built-in name, a splat file, or a TaskScene.
        goal_xy: (2,) goal position of the base (world, metres).
        start: (3,) start (x, y, yaw); default (0, 0, 0) (the CLI uses :data:`START` on the apartment).
        config: :class:`BaseConfig`.
        collision: include the collision cost.
        route: optional (P, 2+) waypoints; the goal cost then tracks the next waypoint ahead.
        device: metric device.
        progress: optional callable(step, distance) per MPC step.
    """
    from ..planners.dynamics import PlanarBase

    cfg = (config or BaseConfig()).validate()
    robot = load_go2() if robot is None or robot == "go2" else robot
    if int(robot.dof) != 3:
        raise SplatplanError(f"run_base needs a planar-base robot (x, y, yaw); {robot.name} has {robot.dof} dofs")
    g = np.asarray(goal_xy, np.float64).reshape(-1)[:2]
    if not np.all(np.isfinite(g)):
        raise SplatplanError(f"goal {g.tolist()} is not finite")
    ts = load_task_scene(scene, n_sigma=cfg.n_sigma, device=device, terrain=base_terrain(cfg))
    lo, hi = ts.splats.bounds()
    if np.any(g < lo[:2]) or np.any(g > hi[:2]):
        raise SplatplanError(f"goal {g.round(3).tolist()} lies outside the scene (x, y in {lo[:2].round(2).tolist()} .. {hi[:2].round(2).tolist()})")
    if _free_yaw(robot, ts.checker, g) is None:
        raise SplatplanError(f"goal {g.round(3).tolist()}: the base collides there at every heading; pick a free goal")
    x = np.zeros(3) if start is None else np.asarray(start, np.float64).reshape(3).copy()
    check_start(robot, ts.checker, x)

    vmax = np.asarray(robot.velocity_limits, np.float64)
    dyn = PlanarBase(robot)
    collision_cost = None
    if collision:
        from ..planners.costs import CollisionCost

        collision_cost = CollisionCost(ts.checker, robot, weight=cfg.w_collision, hit_weight=cfg.w_hit, s2_cap=cfg.collision_s2_cap, time_stride=cfg.collision_stride)
    memory = None
    if cfg.memory and route is None:
        memory = ObstacleMemory(robot, ts.checker, lo, hi, g, cell=cfg.memory_cell_m, radius=cfg.sensor_radius_m, n_yaws=cfg.memory_yaws,
                                inflation_m=cfg.memory_inflation_m, inflation_cost=cfg.memory_inflation_cost,
                                occlusion=cfg.sensor_occlusion, sensor_height=cfg.sensor_height_m)  # fmt: skip
    planner = _BasePlanner(dyn, cfg, vmax, collision_cost, g, recovery=collision and cfg.recovery and route is None, memory=memory)
    wps = None if route is None else np.asarray(route, np.float64)[:, :2]
    track = None if route is None else RouteTracker(route, cfg.route_lookahead_m)
    states = [x.copy()]
    t0 = time.perf_counter()
    n_steps = n_held = 0
    for step in range(cfg.max_steps):
        dist = float(np.linalg.norm(x[:2] - g))
        if progress is not None:
            progress(step, dist)
        if dist < 0.5 * cfg.goal_tol:
            break
        if track is not None:  # the route's point route_lookahead_m ahead of the base's progress, and its heading
            planner.goal, planner.heading_ref = track.target(x[:2])
        u = planner.step(x)
        if collision and cfg.safe_step:
            u, x_next = safe_step(robot, ts.checker, dyn, x, u, cfg.dt)
            if x_next is None:  # held: the nominal ran into it, plan afresh from standing still
                n_held += 1
                x_next = x.copy()
                planner.knots[:] = 0.0
            x = x_next
        else:
            x = dyn.rollout(x, u[None, None, :], cfg.dt)[0, 0]
        states.append(x.copy())
        n_steps += 1
    elapsed = time.perf_counter() - t0
    dist = float(np.linalg.norm(x[:2] - g))
    traj = np.asarray(states)
    clearance, source, _ = trajectory_clearance(robot, ts, traj)
    success = bool(dist < cfg.goal_tol and clearance > 0)
    return TaskResult(
        success=success,
        trajectory=traj,
        min_clearance_m=clearance,
        final_position_error_m=dist,
        time_s=elapsed,
        steps_per_s=n_steps / elapsed if elapsed > 0 else float("nan"),
        collision_cost=bool(collision),
        clearance_source=source,
        message="" if success else ("in collision" if clearance <= 0 else "goal not reached within max_steps"),
        goal={"position": g.tolist()},
        extra={"robot": robot.name, "scene": ts.name, "n_steps": n_steps, "n_held_steps": n_held, "time_to_goal_s": n_steps * cfg.dt, "route": None if wps is None else wps.round(4).tolist(), "n_splats": len(ts.splats), "events": planner.events,
               "memory": None if memory is None else {**memory.stats, "cell_m": memory.cell, "sensor_radius_m": memory.radius, "n_yaws": len(memory.yaws), "shape": list(memory.shape),
                                                        "occlusion": memory.occlusion, "sensor_height_m": memory.sensor_height}},
        maps={} if memory is None else {"memory_blocked": memory.blocked.copy(), "memory_sensed": memory.sensed.copy(), "memory_origin": memory.origin.copy(), "memory_cell": memory.cell},
    )
