"""Quadruped base driving under MPPI (paper Sec. IV, E6's last stage): the Go2 to a goal position
given **only the goal** (e.g. the final node of an RRT path), around obstacles and through
doorways on the collision cost alone. A recipe: a :class:`BaseConfig` (embedding the
:class:`~splatplan.planners.MPPIConfig`), the Go2, a cost list and the MPC loop.

State (x, y, yaw) of the base in the world (metres, radians); controls (vx, vy, wz) in the body
frame, an unclamped cubic B-spline over the horizon, clipped to the robot's velocity limits
(:class:`~splatplan.planners.dynamics.PlanarBase`). Costs: every body and leg ellipsoid of the Go2
at its standing height in the collision cost (one ``query_robot`` per MPC step on the (K, T, 3)
batch, every step of the horizon: with a stride of 2 the base grazed a door post, -3.6 cm exact),
the control effort plus a small yaw-rate cost, and the goal term
(:class:`~splatplan.planners.drive.DriveGoalCost`). Sampling:
:class:`~splatplan.planners.drive.StructuredDrives` (structured drives beside the Gaussian knot
noise, and the optional stagnation recovery); :mod:`splatplan.planners.drive` describes both.

* **Stagnation recovery** (``recovery``) is **off by default**: in the base study it reached no
  goal that plain MPPI missed (3/5 either way; the kitchen goals fail both ways), and it can fire
  while the base is still lining up with a doorway (bedroom goal (1.12, 1.81), seeds 0-5: 5/6
  reached with it, 6/6 without).
* **Sensed-obstacle memory** (``memory``, off by default;
  :class:`~splatplan.planners.memory.ObstacleMemory`): how navigation stacks get out of local
  minima with no prior map (the freespace assumption of D* Lite in unknown terrain). The base keeps
  a coarse occupancy grid (``memory_cell_m``) of the scene box, *unknown = free* at the start;
  every MPC step it senses the cells within ``sensor_radius_m`` that it has not sensed before and
  that are in its line of sight (``sensor_occlusion``: like a 2D lidar at ``sensor_height_m``)
  (blocked: the Go2 collides there at every one of ``memory_yaws`` headings). The goal term then
  reads the **geodesic** distance to the goal on that grid, with an inflation layer
  (``memory_inflation_m``, ``memory_inflation_cost``: the geodesic keeps to the middle of passages
  and doorways; without it the base hugged the door post of the kitchen doorway, every sample
  collided, and it backed out). The collision cost is unchanged. In the base study it reaches the
  two kitchen goals that plain MPPI misses (5/5 against 3/5, in 21-24 s against 16-17 s).

**Conservatism.** The base runs the metric at ``n_sigma = 0.75``: at n_sigma = 1 the splats'
inflation (about 0.13 m per side on the walls) leaves **no** collision-free pose of the Go2 (yaw 0)
in the 0.8 m living-kitchen doorway and a 6 cm band (at yaw 90 deg) in the 0.8 m bedroom-kitchen
one, so the kitchen is unreachable; at 0.75 the free bands of the centre are 16, 28 and 20 cm
(living-kitchen, living-bedroom, bedroom-kitchen). At 0.5 (31, 38, 34 cm) the base grazed the
exact boxes by 2-3 cm in tight spots, which the metric at 0.5 did not see. The exact clearance
to the boxes is what the studies report.

With ``route`` (a path, e.g. from :func:`~splatplan.planners.route.plan_route`), the goal term follows the route instead
(:class:`~splatplan.planners.drive.RouteTracker`: the point ``route_lookahead_m`` ahead of the
base's progress along it, and the heading term faces the route's yaw there, the heading the RRT
found free) and the recovery and the memory are off (``--route`` in the CLI, and by default there
when the straight line to the goal is blocked).

With ``safe_step`` (on) each executed control period is checked densified before it is driven
(:func:`~splatplan.tasks._common.safe_step`): a colliding one is halved twice, else the base holds
still and MPPI restarts from standing still (``extra["n_held_steps"]``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Literal

import numpy as np

from .._config import NESTED_SKIP, bounded
from ..errors import SplatplanError
from ..planners.bounds import box_margin, planning_box, reach_radius
from ..planners.costs import StridedCollisionTerms
from ..planners.drive import DriveTerms
from ..planners.memory import MemoryTerms
from ..planners.mppi import MPPIConfig
from ._common import TaskConfig, TaskResult, base_terrain, check_start, load_task_scene, safe_step

if TYPE_CHECKING:
    from ..robots.robot import Robot

__all__ = ["FOOT_CLEARANCE", "START", "BaseConfig", "load_go2", "run_base"]

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


def _base_mppi() -> MPPIConfig:
    """The base's MPPI settings: K = 64, T = 20 steps of 0.2 s, 6 unclamped knots, one iteration per step."""
    return MPPIConfig(n_samples=64, horizon=20, n_knots=6, dt=0.2, temperature=0.5, noise_sigma=(0.6, 0.4, 0.3), n_iters=1, clamped_spline=False, report_nominal=False)


@dataclass
class BaseConfig(TaskConfig, StridedCollisionTerms, DriveTerms, MemoryTerms, n_sigma=0.75, w_collision=2.0, w_hit=10.0, collision_s2_cap=2.0, collision_stride=1):
    # n_sigma 0.75: see the module docstring. w_hit kept small: a large one makes every sample that grazes a
    # door post lose to standing still, and the base never threads a doorway
    """Knobs of :func:`run_base` (MPPI over body-frame velocity B-splines)."""

    #: MPPI settings (noise_sigma: vx m/s, vy m/s, wz rad/s; the control bounds are the robot's velocity limits)
    mppi: MPPIConfig = field(default_factory=_base_mppi, metadata={NESTED_SKIP: ("u_min", "u_max")})
    #: maximum MPC steps
    max_steps: int = bounded(250, ge=1)
    #: weight of the yaw rate sum_t wz^2 dt (keeps the heading from drifting; the base walks
    #: sideways when it has to)
    w_yaw_rate: float = bounded(0.1, ge=0)
    #: weight of the control effort
    w_control: float = bounded(0.02, ge=0)
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


def base_box(ts, robot: Robot, box=None) -> tuple[np.ndarray, np.ndarray]:
    """(lo (3,), hi (3,)) world box where the base may go: x, y from ``box`` ((lo (2,), hi (2,)),
    metres) or :func:`~splatplan.planners.bounds.planning_box` (the scene's bounds grown by the
    footprint diameter), z the scene's bounds."""
    lo, hi = (np.asarray(b, np.float64).copy() for b in ts.splats.bounds())
    if box is None:
        blo, bhi = planning_box(ts.splats, robot)
    else:
        blo, bhi = (np.asarray(b, np.float64).reshape(-1) for b in box)
    lo[:2], hi[:2] = blo[:2], bhi[:2]
    return lo, hi


def _memory_box(ts, robot: Robot, box, start: np.ndarray, goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The obstacle memory's (lo (3,), hi (3,)): the given box, else the scene's bounds grown to hold
    the start and the goal with a footprint radius around them (a room keeps its walls as the edge)."""
    if box is not None:
        return base_box(ts, robot, box)
    lo, hi = (np.asarray(b, np.float64).copy() for b in ts.splats.bounds())
    r = reach_radius(robot)
    ends = np.stack([start[:2], goal[:2]])
    lo[:2] = np.minimum(lo[:2], ends.min(axis=0) - r)
    hi[:2] = np.maximum(hi[:2], ends.max(axis=0) + r)
    return lo, hi


def run_base(
    robot: Robot | Literal["go2"] | None,
    scene,
    goal_xy,
    *,
    start=None,
    config: BaseConfig | None = None,
    collision: bool = True,
    route: np.ndarray | None = None,
    box=None,
    device: str | None = "auto",
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
        route: optional (P, 2) or (P, 3) waypoints (x, y[, yaw]); the goal term then tracks the
            route (:class:`~splatplan.planners.drive.RouteTracker`, ``route_lookahead_m`` ahead).
        box: (lo (2,), hi (2,)) world x, y (metres) where the base may go: the goal must lie in it
            and the route's planner stays in it; default :func:`~splatplan.planners.bounds.planning_box`,
            the scene's bounds grown by the robot's footprint diameter.
        device: metric device.
        progress: optional callable(step, distance) per MPC step.
    """
    from ..planners import MPPI, ControlEffortCost, PlanarBase
    from ..planners.drive import RouteTracker
    from ..planners.route import free_yaw

    cfg = (config or BaseConfig()).validate()
    robot = load_go2() if robot is None or robot == "go2" else robot
    if int(robot.dof) != 3:
        raise SplatplanError(f"run_base needs a planar-base robot (x, y, yaw); {robot.name} has {robot.dof} dofs")
    g = np.asarray(goal_xy, np.float64).reshape(-1)[:2]
    if not np.all(np.isfinite(g)):
        raise SplatplanError(f"goal {g.tolist()} is not finite")
    ts = load_task_scene(scene, n_sigma=cfg.n_sigma, device=device, terrain=base_terrain(cfg))
    lo, hi = base_box(ts, robot, box)
    if np.any(g < lo[:2]) or np.any(g > hi[:2]):
        how = "the given box" if box is not None else f"the scene's bounds grown by {box_margin(robot):.2f} m, the robot's footprint diameter"
        raise SplatplanError(f"goal {g.round(3).tolist()} lies outside the scene's planning box x, y in {lo[:2].round(2).tolist()} .. {hi[:2].round(2).tolist()} "
                             f"({how}); widen it with --box X,Y X,Y (box= in Python)")  # fmt: skip
    if free_yaw(robot, ts.checker, g) is None:
        raise SplatplanError(f"goal {g.round(3).tolist()}: the base collides there at every heading; pick a free goal")
    x = np.zeros(3) if start is None else np.asarray(start, np.float64).reshape(3).copy()
    check_start(robot, ts.checker, x)

    vmax = np.asarray(robot.velocity_limits, np.float64)
    dyn = PlanarBase(robot)
    memory = cfg.obstacle_memory(robot, ts.checker, *_memory_box(ts, robot, box, x, g), g) if route is None else None
    goal_cost = cfg.goal_cost(g, field=memory)
    costs = [ControlEffortCost(cfg.w_control, {2: cfg.w_yaw_rate}), goal_cost]
    if collision:
        costs.insert(0, cfg.collision_cost(ts.checker, robot))
    drives = cfg.drives(goal_cost, recovery=collision and cfg.recovery and route is None)
    mppi = MPPI(dyn, None, replace(cfg.mppi, u_min=tuple(-vmax), u_max=tuple(vmax)), costs=costs, sampler=drives)
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
            goal_cost.goal, goal_cost.heading_ref = track.target(x[:2])
        if memory is not None:
            memory.sense(x[:2])
        u, _ = mppi.step(x)
        if collision and cfg.safe_step:
            u, x_next = safe_step(robot, ts.checker, dyn, x, u, cfg.mppi.dt)
            if x_next is None:  # held: the nominal ran into it, plan afresh from standing still
                n_held += 1
                x_next = x.copy()
                mppi.reset()
            x = x_next
        else:
            x = dyn.rollout(x, u[None, None, :], cfg.mppi.dt)[0, 0]
        states.append(x.copy())
        n_steps += 1
    elapsed = time.perf_counter() - t0
    dist = float(np.linalg.norm(x[:2] - g))
    return TaskResult.of_run(
        robot, ts, states, dist, cfg.goal_tol, elapsed, n_steps, collision,
        goal={"position": g.tolist()},
        extra={"robot": robot.name, "scene": ts.name, "n_steps": n_steps, "n_held_steps": n_held, "time_to_goal_s": n_steps * cfg.mppi.dt, "route": None if wps is None else wps.round(4).tolist(), "n_splats": len(ts.splats), "events": drives.events,
               "memory": None if memory is None else {**memory.stats, "cell_m": memory.cell, "sensor_radius_m": memory.radius, "n_yaws": len(memory.yaws), "shape": list(memory.shape),
                                                        "occlusion": memory.occlusion, "sensor_height_m": memory.sensor_height}},
        maps={} if memory is None else {"memory_blocked": memory.blocked.copy(), "memory_sensed": memory.sensed.copy(), "memory_origin": memory.origin.copy(), "memory_cell": memory.cell},
    )
