"""Arm reaching under MPPI (paper Sec. II-D / IV, E5 without the image): a 7-DoF arm to an
end-effector pose, with the collision cost over every link ellipsoid.

Controls: joint velocities (rad/s) as a cubic B-spline over the horizon (MPPI knots), clipped to
``velocity_scale * robot.velocity_limits``; joint positions saturate at the limits
(:class:`~splatplan.planners.dynamics.JointIntegrator`) and a :class:`JointLimitCost` keeps samples
away from them. Cost per sample (:mod:`splatplan.planners.costs`):

* :class:`GoalPoseCost` on the end-effector link: position (m) + orientation (rad), summed over the
  horizon with extra weight on the last step;
* :class:`CollisionCost`: the CollisionSplatting cost of **every** robot ellipsoid, one
  ``query_robot`` per MPPI iteration on the (K, T, dof) batch, plus a count of colliding ellipsoids
  (and optional self-collision);
* :class:`ControlEffortCost`, :class:`JointLimitCost`, and a posture term toward the
  IK solution of the goal nearest to the start (collision-free ones only when the collision cost is on; resolves the 7-DoF redundancy; the
  task cost is still the end-effector pose).

Warm start by shifting the knots one control period (MPPI's own); the knots are an unclamped
B-spline so that the applied first control is set by knots that shape the whole rollout; the
knot noise shrinks near the goal (``noise_anneal_m``). The collision cost may query every
``collision_stride``-th step of the horizon. The goal pose is checked for reachability by IK
(:func:`~splatplan.robots.ik.check_reachable`) before any step: an unreachable goal is an error.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from .._config import NESTED_SKIP, bounded
from ..errors import SplatplanError
from ..planners.dynamics import JointIntegrator
from ..planners.costs import JointVelocityTerms, StridedCollisionTerms
from ..planners.mppi import MPPIConfig
from ..robots.ik import check_reachable, rotation_error
from ._common import TaskConfig, TaskResult, TaskScene, check_start, load_task_scene, run_clearance

if TYPE_CHECKING:
    from ..robots.robot import Robot

__all__ = ["ArmConfig", "run_arm"]


def _arm_mppi() -> MPPIConfig:
    """The arm's MPPI settings: K = 64, T = 16, 5 unclamped knots (the applied first control is set
    by knots that shape the whole rollout), one iteration per step, pruning at margin 40."""
    return MPPIConfig(n_samples=64, horizon=16, n_knots=5, dt=0.1, temperature=0.3, noise_sigma=0.35, n_iters=1, clamped_spline=False, report_nominal=False, prune_margin=40.0)


@dataclass
class ArmConfig(TaskConfig, StridedCollisionTerms, JointVelocityTerms, velocity_scale=0.4, n_sigma=1.0, w_collision=2.0, w_hit=20.0, collision_s2_cap=1.4, collision_stride=1):
    """Knobs of :func:`run_arm` (MPPI over joint-velocity B-splines).

    collision_stride is 1: the hand moves up to ~4 cm per step, and at stride 2 the tight model's thin
    finger ellipsoids (9 mm semi-axes) clipped the front wall's top between evaluated steps
    (eval arm: 2/5 successes).
    """

    #: MPPI settings (noise_sigma in rad/s; the control bounds come from velocity_scale)
    mppi: MPPIConfig = field(default_factory=_arm_mppi, metadata={NESTED_SKIP: ("u_min", "u_max")})
    #: near the goal the noise shrinks: std x clip(position error / this (m), noise_floor, 1)
    noise_anneal_m: float = bounded(0.3, gt=0)
    #: smallest noise fraction of the annealing
    noise_floor: float = bounded(0.05, ge=0, le=1)
    #: maximum MPC steps
    max_steps: int = bounded(90, ge=1)
    #: weight of the end-effector position error (per metre, per step)
    w_position: float = bounded(4.0, ge=0)
    #: weight of the end-effector orientation error (per radian, per step)
    w_orientation: float = bounded(1.0, ge=0)
    #: extra weight of the last step of the goal cost (x the per-step weight)
    terminal_factor: float = bounded(4.0, ge=0)
    #: cost per step with a self-collision (0 = off)
    w_self_collision: float = bounded(0.0, ge=0)
    #: weight of a posture term sum_t |q_t - q_ref|^2 that resolves the arm's redundancy: q_ref is
    #: the IK solution of the goal pose nearest to the start, among the collision-free ones when the
    #: collision cost is on (the no-collision baseline uses no scene information at all)
    w_posture: float = bounded(1.0, ge=0)
    #: end-effector link
    ee_link: str = "panda_hand_tcp"
    #: success: final position error below this (m) with a positive clearance throughout
    position_tol: float = bounded(0.02, gt=0)
    #: orientation error (degrees) that counts as reached for the early stop (reported, not in success)
    orientation_tol_deg: float = bounded(10.0, gt=0, le=180)
    #: stop early once the position error is below this (m) and the orientation within tolerance
    stop_tol: float = bounded(0.008, ge=0)



def _ee_error(robot, q: np.ndarray, li: int, p_goal: np.ndarray, r_goal: np.ndarray | None) -> tuple[float, float]:
    t = robot.link_poses(np.asarray(q, np.float64))[li]
    pe = float(np.linalg.norm(t[:3, 3] - p_goal))
    re = 0.0 if r_goal is None else float(np.linalg.norm(rotation_error(t[:3, :3], r_goal)))
    return pe, re


def _goal_pose(goal_position, goal_quat) -> tuple[np.ndarray, np.ndarray | None]:
    """Checked goal position (3,) and unit wxyz quaternion (4,) | None."""
    p_goal = np.asarray(goal_position, np.float64).reshape(3)
    if not np.all(np.isfinite(p_goal)):
        raise SplatplanError(f"goal position {p_goal.tolist()} is not finite")
    if goal_quat is None:
        return p_goal, None
    quat = np.asarray(goal_quat, np.float64).reshape(4)
    if not np.all(np.isfinite(quat)) or np.linalg.norm(quat) < 1e-8:
        raise SplatplanError(f"goal quaternion {quat.tolist()} must be finite and non-zero (wxyz)")
    return p_goal, quat / np.linalg.norm(quat)


def _posture_reference(robot, ts: TaskScene, p_goal, quat, q: np.ndarray, cfg: ArmConfig, collision: bool) -> np.ndarray:
    """The IK solution of the goal pose nearest to ``q`` (collision-free ones first when the
    collision cost is on; the no-collision baseline knows nothing of the scene). Raises when the
    goal is unreachable."""
    sols = check_reachable(robot, p_goal, quat, cfg.ee_link, seed=cfg.mppi.seed)
    pool = sols
    if collision:
        free = ~np.asarray(ts.checker.collides_robot(robot, sols)).any(axis=-1)
        pool = sols[free] if np.any(free) else sols
    return pool[np.argmin(np.sum((pool - q) ** 2, axis=1))]


def _arm_costs(robot, ts: TaskScene, p_goal, quat, q_ref: np.ndarray, cfg: ArmConfig, collision: bool) -> list:
    """The cost list of :func:`run_arm` (see the module docstring)."""
    from ..planners.costs import GoalPoseCost, StateCost, fk_device

    costs = [
        GoalPoseCost(robot, position=p_goal, quat=quat, link=cfg.ee_link, position_weight=cfg.w_position, orientation_weight=cfg.w_orientation, terminal_factor=cfg.terminal_factor,
                     device=fk_device(ts.checker)),
        *cfg.joint_costs(robot),
    ]  # fmt: skip
    if cfg.w_posture > 0:
        costs.append(StateCost(lambda s: np.sum((s - q_ref) ** 2, axis=-1), weight=cfg.w_posture, name="posture"))
    if collision:
        costs.insert(0, cfg.collision_cost(ts.checker, robot, self_collision_weight=cfg.w_self_collision))
    return costs


def run_arm(robot: Robot | str, scene, goal_position, goal_quat=None, *, config: ArmConfig | None = None, collision: bool = True, q0=None, device: str | None = "auto", check_goal: bool = True,
            progress=None) -> TaskResult:  # fmt: skip
    """Reach an end-effector pose with MPPI (see the module docstring).

    Args:
        robot: a :class:`~splatplan.robots.Robot` (or a name, e.g. "panda").
        scene: a built-in name, a splat file, or a :class:`TaskScene`.
        goal_position: (3,) world frame, metres.
        goal_quat: (4,) wxyz world <- end-effector link, or None (position only).
        config: :class:`ArmConfig`.
        collision: include the collision cost (False: the "without collision" baseline).
        q0: start configuration (default ``robot.q_default``).
        device: metric device.
        check_goal: run the IK reachability check first.
        progress: optional callable(step, position_error) per MPC step.

    Returns:
        :class:`TaskResult` (``trajectory`` in joint space).
    """
    from ..planners import MPPI
    from ..robots import load_robot
    from ..scenes.splats import quat_to_rotmat

    cfg = (config or ArmConfig()).validate()
    robot = load_robot(robot)
    if cfg.ee_link not in robot.link_names:
        raise SplatplanError(f"robot {robot.name} has no end-effector link {cfg.ee_link!r}; links: {', '.join(robot.link_names)}")
    p_goal, quat = _goal_pose(goal_position, goal_quat)
    ts = load_task_scene(scene, n_sigma=cfg.n_sigma, device=device)
    q = robot.check_q(robot.q_default if q0 is None else q0).reshape(robot.dof).copy()
    q_ref = _posture_reference(robot, ts, p_goal, quat, q, cfg, collision) if check_goal else np.asarray(robot.q_default, np.float64)
    check_start(robot, ts.checker, q)

    vmax = cfg.velocity_bound(robot)
    dyn = JointIntegrator(robot, velocity_limits=vmax)
    mppi = MPPI(dyn, None, replace(cfg.mppi, u_min=tuple(-vmax), u_max=tuple(vmax)), costs=_arm_costs(robot, ts, p_goal, quat, q_ref, cfg, collision))
    li = robot.link_names.index(cfg.ee_link)
    r_goal = None if quat is None else quat_to_rotmat(quat)
    states = [q.copy()]
    t0 = time.perf_counter()
    n_steps = 0
    for step in range(cfg.max_steps):
        pe, re = _ee_error(robot, q, li, p_goal, r_goal)
        if progress is not None:
            progress(step, pe)
        if pe < cfg.stop_tol and np.rad2deg(re) < cfg.orientation_tol_deg:
            break
        mppi.set_noise_scale(np.clip(pe / cfg.noise_anneal_m, cfg.noise_floor, 1.0))  # finer near the goal
        u, _ = mppi.step(q)
        q = dyn.rollout(q, u[None, None, :], cfg.mppi.dt)[0, 0]
        states.append(q.copy())
        n_steps += 1
    elapsed = time.perf_counter() - t0
    pe, re = _ee_error(robot, q, li, p_goal, r_goal)
    traj = np.asarray(states)
    clear = run_clearance(robot, ts, traj)  # (every link's and the moving ones' minimum from one evaluation)
    clearance_moving = clear[1]
    ee = robot.link_poses(traj)[:, li, :3, 3]
    return TaskResult.of_run(  # success: position error and clearance; the orientation error is reported beside it
        robot, ts, traj, pe, cfg.position_tol, elapsed, n_steps, collision, clearance=clear,
        final_orientation_error_deg=float(np.rad2deg(re)),
        goal={"position": p_goal.tolist(), "quat_wxyz": None if quat is None else quat.tolist(), "link": cfg.ee_link},
        extra={"robot": robot.name, "scene": ts.name, "n_steps": n_steps, "ee_trace": ee.round(5).tolist(), "n_splats": len(ts.splats),
               "min_clearance_moving_links_m": clearance_moving},  # fmt: skip
    )
