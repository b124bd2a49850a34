"""Quadruped base driving under MPPI (paper Sec. IV, E6's last stage): the Go2 to a goal position
given **only the goal** (e.g. the final node of an RRT path), around obstacles and through
doorways on the collision cost alone.

State (x, y, yaw) of the base in the world (metres, radians); controls (vx, vy, wz) in the body
frame, a cubic B-spline over the horizon, clipped to the robot's velocity limits
(:class:`~splatplan.planners.dynamics.PlanarBase`). Every body and leg ellipsoid of the Go2 at its
standing height enters the collision cost (one ``query_robot`` per MPPI iteration on the
(K, T, 3) batch). Task cost: distance of the base to the goal (:class:`GoalPoseCost` on the state's
x, y), summed over the horizon with extra weight on the last step.

What lets it get out of a room through a doorway without a route (see :class:`BaseConfig`): a
4 s horizon, wide translation noise but little yaw-rate noise (yaw noise integrates into headings
that hit the door posts), and a small per-hit cost next to the smooth collision cost. With ``route`` (a
path, e.g. from :func:`plan_route`), the goal cost follows the route's waypoints instead
(``--route`` in the CLI).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import SplatplanError
from ._common import TaskResult, check_start, load_task_scene, strided_collision_cost, trajectory_clearance

__all__ = ["FOOT_CLEARANCE", "BaseConfig", "load_go2", "plan_route", "run_base"]

#: The Go2's feet ellipsoids are lifted this far (m) above the floor (as in a trot's swing phase), so
#: the floor itself is not a collision.
FOOT_CLEARANCE = 0.04


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
    n_samples: int = 64
    #: horizon T (control steps)
    horizon: int = 20
    #: B-spline knots per control over the horizon
    n_knots: int = 6
    #: control period (s)
    dt: float = 0.2
    #: MPPI temperature
    temperature: float = 0.5
    #: knot noise std (vx m/s, vy m/s, wz rad/s)
    noise_sigma: tuple[float, float, float] = (0.6, 0.3, 0.25)
    #: MPPI iterations per MPC step
    n_iters: int = 1
    #: maximum MPC steps
    max_steps: int = 250
    #: weight of the distance to the goal (per metre, per step)
    w_goal: float = 1.0
    #: extra weight of the last step of the goal cost
    terminal_factor: float = 5.0
    #: weight of facing the goal: sum_t (1 - cos(yaw_t - bearing to the goal)) (a walking robot
    #: moves best forward; 0 = off)
    w_heading: float = 0.0
    #: weight of the summed CollisionSplatting cost
    w_collision: float = 2.0
    #: cost per (step, ellipsoid) in collision (kept small: a large one makes every sample that
    #: grazes a door post lose to standing still, and the base never threads a doorway)
    w_hit: float = 2.0
    #: weight of the control effort
    w_control: float = 0.02
    #: conservatism of the metric (n_sigma)
    n_sigma: float = 1.0
    #: neighbourhood of the rollouts' collision cost (checker s2_cap for MPPI queries)
    collision_s2_cap: float = 2.0
    #: query the collision cost on every stride-th step of the horizon
    collision_stride: int = 2
    #: success: final distance to the goal below this (m)
    goal_tol: float = 0.2
    #: height of the floor (m): splats below floor + ground_band are terrain, not obstacles (None: keep all)
    ground_z: float | None = 0.0
    #: thickness of the removed ground band (m)
    ground_band: float = 0.03
    #: noise seed
    seed: int = 0


def plan_route(robot, checker, start, goal_xy, time_budget_s: float = 60.0, seed: int = 0) -> np.ndarray | None:
    """Global route on the base's SE(2) with the batched RRT: (P, 3) configurations (x, y, yaw),
    or None when none is found within ``time_budget_s``.

    The goal's yaw is free: the RRT goal is the goal position at the collision-free heading nearest
    to the bearing from the start."""
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
    cfg = RRTConfig(box_lo=(float(lo[0]), float(lo[1]), -np.pi), box_hi=(float(hi[0]), float(hi[1]), np.pi), time_limit_s=time_budget_s, seed=seed, goal_tolerance=0.1)
    res = RRT(checker, cfg, robot=robot).plan(start, np.array([g[0], g[1], yaw]))
    if not res.success:
        return None
    return np.asarray(res.path)


def _free_yaw(robot, checker, xy) -> float | None:
    """A yaw at which the base at ``xy`` is collision-free (None if every one of 16 collides)."""
    yaws = np.linspace(-np.pi, np.pi, 16, endpoint=False)
    q = np.stack([np.full(16, xy[0]), np.full(16, xy[1]), yaws], axis=1)
    free = ~np.asarray(checker.collides_robot(robot, q)).any(axis=-1)
    return float(yaws[np.argmax(free)]) if free.any() else None


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
        start: (3,) start (x, y, yaw); default (0, 0, 0).
        config: :class:`BaseConfig`.
        collision: include the collision cost.
        route: optional (P, 2+) waypoints; the goal cost then tracks the next waypoint ahead.
        device: metric device.
        progress: optional callable(step, distance) per MPC step.
    """
    from ..planners import MPPI, MPPIConfig
    from ..planners.bspline import UniformBSpline
    from ..planners.costs import ControlEffortCost, GoalPoseCost, StateCost
    from ..planners.dynamics import PlanarBase

    cfg = config or BaseConfig()
    robot = load_go2() if robot is None or robot == "go2" else robot
    if int(robot.dof) != 3:
        raise SplatplanError(f"run_base needs a planar-base robot (x, y, yaw); {robot.name} has {robot.dof} dofs")
    g = np.asarray(goal_xy, np.float64).reshape(-1)[:2]
    if not np.all(np.isfinite(g)):
        raise SplatplanError(f"goal {g.tolist()} is not finite")
    ts = load_task_scene(scene, n_sigma=cfg.n_sigma, device=device, ground_below=None if cfg.ground_z is None else cfg.ground_z + cfg.ground_band)
    lo, hi = ts.splats.bounds()
    if np.any(g < lo[:2]) or np.any(g > hi[:2]):
        raise SplatplanError(f"goal {g.round(3).tolist()} lies outside the scene (x, y in {lo[:2].round(2).tolist()} .. {hi[:2].round(2).tolist()})")
    if _free_yaw(robot, ts.checker, g) is None:
        raise SplatplanError(f"goal {g.round(3).tolist()}: the base collides there at every heading; pick a free goal")
    x = np.zeros(3) if start is None else np.asarray(start, np.float64).reshape(3).copy()
    check_start(robot, ts.checker, x)

    vmax = np.asarray(robot.velocity_limits, np.float64)
    dyn = PlanarBase(robot)
    goal_cost = GoalPoseCost(None, position=g, state_dims=(0, 1), position_weight=cfg.w_goal, terminal_factor=cfg.terminal_factor)
    costs = [goal_cost, ControlEffortCost(cfg.w_control)]
    if cfg.w_heading > 0:

        def heading(s: np.ndarray) -> np.ndarray:  # (K, T, 3) -> (K, T)
            tgt = goal_cost.position
            bearing = np.arctan2(tgt[1] - s[..., 1], tgt[0] - s[..., 0])
            near = np.linalg.norm(s[..., :2] - tgt, axis=-1) < 0.3  # no heading at the goal itself
            return np.where(near, 0.0, 1.0 - np.cos(s[..., 2] - bearing))

        costs.append(StateCost(heading, weight=cfg.w_heading, name="heading"))
    if collision:
        costs.insert(0, strided_collision_cost(ts.checker, robot, cfg.collision_stride, weight=cfg.w_collision, hit_weight=cfg.w_hit, s2_cap=cfg.collision_s2_cap))
    mcfg = MPPIConfig(
        n_samples=cfg.n_samples, horizon=cfg.horizon, n_knots=cfg.n_knots, dt=cfg.dt, temperature=cfg.temperature,
        noise_sigma=tuple(cfg.noise_sigma), n_iters=cfg.n_iters, u_min=tuple(-vmax), u_max=tuple(vmax), seed=cfg.seed,
    )  # fmt: skip
    mppi = MPPI(dyn, ts.checker if collision else None, mcfg, costs=costs)
    mppi.spline = UniformBSpline(cfg.n_knots, cfg.horizon, clamped=False)  # see tasks.arm
    wps = None if route is None else np.asarray(route, np.float64)[:, :2]
    states = [x.copy()]
    t0 = time.perf_counter()
    n_steps = 0
    for step in range(cfg.max_steps):
        dist = float(np.linalg.norm(x[:2] - g))
        if progress is not None:
            progress(step, dist)
        if dist < 0.5 * cfg.goal_tol:
            break
        if wps is not None:  # track the first waypoint more than 1 m ahead along the route
            i = int(np.argmin(np.linalg.norm(wps - x[:2], axis=1)))
            ahead = [j for j in range(i, len(wps)) if np.linalg.norm(wps[j] - x[:2]) > 1.0]
            goal_cost.position = wps[ahead[0]] if ahead else g
        u, _ = mppi.step(x)
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
        extra={"robot": robot.name, "scene": ts.name, "n_steps": n_steps, "time_to_goal_s": n_steps * cfg.dt, "route": None if wps is None else wps.round(4).tolist(), "n_splats": len(ts.splats)},
    )
