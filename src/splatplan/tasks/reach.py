"""Visual reaching (paper Sec. IV-A, E5): drive a 7-DoF arm so that its wrist camera sees a target
image, with MPPI over joint-velocity B-splines and the terminal image cost.

Camera: a pinhole camera at the Panda's ``panda_hand_tcp`` frame (OpenCV axes = the TCP axes: it
looks along the gripper's z axis), :func:`~splatplan.render.cameras.wrist_camera`.

Cost per sample (:mod:`splatplan.planners.costs`, :class:`~splatplan.planners.ImageCost`):

* image: ``w_image log(1 + c / image_log_eps)`` with ``c = ||enc(I_target) - enc(I(x_goal))||^2``
  (+ patch tokens for encoders that have them; features L2-normalised so that every encoder has
  the same cost scale) of the wrist view at the goal time, **one batched render per MPPI
  iteration**, plus ``w_empty`` x the fraction of the view showing no scene inside c (an empty view
  is constant, which a correlation-type embedding scores like a poor match). The log keeps MPPI
  weighing relative progress near the goal, where raw differences between samples vanish.
  The default encoder ``thumbnail`` is here a 2-band Laplacian pyramid of 4 and 8 px thumbnails
  of the 64 px render (:func:`reach_encoder`). Area averaging makes it a smooth function of the
  camera pose; finer bands (16..64 px) of these renders vary with every sub-pixel shift of the
  splats' texture, which roughens the cost into look-alike minima a few centimetres off (the
  4..64 px pyramid left one goal of the study 7 cm off and converged slowly on the others);
* collision (optional: the "with / without collision cost" rows of Table IV): the
  CollisionSplatting cost of every robot ellipsoid, one ``query_robot``;
* control effort and joint-limit penalty.
  These path costs cover the rollout steps up to the goal time only (the tail is never executed).

Schedule: shrinking horizon with a fixed goal time (:class:`~splatplan.planners.goal_time.GoalTimeMPC`,
whose fields are flat in :class:`ReachConfig`): a multi-start initial plan with goal-state
refinement, then one control a step with the image rendered at step ``T - 1 - s`` of the rollout
after ``s`` executed steps; after T steps the arm is where the plan ended. With the collision
cost, a second initial plan searches the goal without the path's collision cost (a wall between
the start and a hidden goal would otherwise hold the plan in front of it, at a look-alike view); it
is kept when its image cost is lower, and when its path collides an RRT-Connect path to its goal
state (the task's checker) seeds it (``goal_search``; the goal search of
:class:`~splatplan.planners.goal_time.GoalTimeMPC`). K = 32, T = 48, 8 knots,
dt = 0.05 s and temperature 0.1 follow the paper's authors' example; images are 64x64 here
(224x224 in the paper). Goals and the start of the studies: :mod:`splatplan.planners.reach_goals`.

The controller sees the target image only: no goal pose, configuration or collision information
enters the without-collision run (the start is an IK solution of a fixed camera pose; the goals
are chosen collision-free by the study, as in the paper).

Units: metres, radians, seconds; world frame z up (the tabletop scene's).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from .._config import NESTED_SKIP, bounded, check_order
from ..errors import PlanningError, SplatplanError
from ..planners import plan
from ..planners.costs import JointVelocityTerms, StridedCollisionTerms
from ..planners.goal_time import GoalTimeMPC, GoalTimeSchedule
from ..planners.image_cost import ImageTerms
from ..planners.mppi import MPPI, MPPIConfig
from ..planners.rrt_types import RRTConfig
from ._common import TaskConfig, check_start, load_task_scene, run_clearance

if TYPE_CHECKING:
    from ..robots.robot import Robot

__all__ = ["ReachConfig", "ReachResult", "reach_encoder", "run_reach"]


def _reach_mppi() -> MPPIConfig:
    """The reach's MPPI settings (the paper's authors' example): K = 32, T = 48, 8 knots, dt = 0.05 s, temperature 0.1."""
    return MPPIConfig(n_samples=32, horizon=48, n_knots=8, dt=0.05, temperature=0.1, noise_sigma=0.25, n_iters=1)


@dataclass
class ReachConfig(TaskConfig, StridedCollisionTerms, JointVelocityTerms, GoalTimeSchedule, ImageTerms, velocity_scale=0.6, n_sigma=1.0, w_collision=0.1, w_hit=10.0, collision_s2_cap=1.3, collision_stride=2):
    """Knobs of :func:`run_reach` (MPPI over joint-velocity B-splines with the image cost)."""

    #: MPPI settings (noise_sigma in rad/s; the horizon is the executed steps too: a shrinking horizon; the iterations
    #: per step come from the schedule below, the control bounds from velocity_scale)
    mppi: MPPIConfig = field(default_factory=_reach_mppi, metadata={NESTED_SKIP: ("u_min", "u_max", "n_iters", "report_nominal")})
    #: rendered image side (pixels, square)
    image_size: int = bounded(64, ge=1)
    #: horizontal field of view of the wrist camera (degrees)
    fov_deg: float = bounded(70.0, ge=0.01, le=179)
    #: side the encoder resizes images to (None = its default: 8 for the reach thumbnail pyramid, 224 for EfficientNet / DINOv2)
    encoder_image_size: int | None = bounded(None, ge=1)
    #: bands of the thumbnail encoder's Laplacian pyramid (1 = the single 16x16 thumbnail)
    thumbnail_levels: int = bounded(2, ge=1)
    #: splats of a built-in scene (fewer = faster renders; the clearance uses the exact geometry)
    n_splats: int = bounded(60_000, ge=1)
    #: link carrying the wrist camera (camera axes = link axes, OpenCV: looks along link z)
    camera_link: str = "panda_hand_tcp"
    #: success: final camera translation error below this (m) ...
    position_tol: float = bounded(0.05, gt=0)
    #: ... rotation error below this (degrees) and positive clearance
    orientation_tol_deg: float = bounded(15.0, gt=0, le=180)
    #: intermediate wrist views kept for the figures
    n_views: int = bounded(6, ge=0)
    #: with the collision cost: a second initial plan searches the goal without the path's collision cost;
    #: kept when its image cost is lower, with a collision-free RRT-Connect path to its goal state when it
    #: collides (GoalTimeMPC's goal search and route); the collision cost acts from there on. False = the
    #: collision-aware initial plan only
    goal_search: bool = True
    #: time limit of that RRT-Connect route (s)
    route_time_s: float = bounded(2.0, gt=0)

    def check(self) -> None:
        check_order(self, "refine_sigma_min", "refine_sigma")


@dataclass
class ReachResult:
    """One visual-reaching run.

    Attributes:
        trajectory: (S + 1, 7) executed joint configurations (rad).
        final_image: (H, W, 3) wrist view at the end.
        views: [(step, (H, W, 3) image)] intermediate wrist views.
        camera_trace: (S + 1, 3) wrist-camera positions (world, m).
        translation_error_m / rotation_error_deg: final camera pose vs the goal camera pose (NaN
            without a goal pose).
        min_clearance_m: smallest clearance of any link ellipsoid over the densified trajectory.
        image_cost_trace: (S,) lowest sampled image cost per MPC step (weighted).
        iterations: MPPI iterations in all; time_s: wall clock of the MPC loop.
    """

    trajectory: np.ndarray
    final_image: np.ndarray
    views: list
    camera_trace: np.ndarray
    translation_error_m: float
    rotation_error_deg: float
    min_clearance_m: float
    clearance_source: str
    image_cost_trace: np.ndarray
    iterations: int
    time_s: float
    collision_cost: bool
    encoder: str
    success: bool
    extra: dict = field(default_factory=dict)

    @property
    def steps_per_s(self) -> float:
        return (len(self.trajectory) - 1) / self.time_s if self.time_s > 0 else float("nan")

    @property
    def iterations_per_s(self) -> float:
        return self.iterations / self.time_s if self.time_s > 0 else float("nan")

    def summary(self) -> dict:
        """JSON-friendly numbers (no images)."""
        f = lambda v: None if not np.isfinite(v) else round(float(v), 6)  # noqa: E731
        return {
            "success": bool(self.success),
            "collision_cost": bool(self.collision_cost),
            "encoder": self.encoder,
            "translation_error_m": f(self.translation_error_m),
            "rotation_error_deg": f(self.rotation_error_deg),
            "min_clearance_m": f(self.min_clearance_m),
            "clearance_source": self.clearance_source,
            "mpc_steps": len(self.trajectory) - 1,
            "mppi_iterations": int(self.iterations),
            "time_s": round(self.time_s, 3),
            "mpc_steps_per_s": f(self.steps_per_s),
            "mppi_iterations_per_s": f(self.iterations_per_s),
            "final_q": np.asarray(self.trajectory[-1]).round(5).tolist(),
            **self.extra,
        }


def reach_encoder(name: str = "thumbnail", weights: str | None = None, device: str | None = "auto", config: ReachConfig | None = None):
    """The encoder of a reach run: :func:`~splatplan.encoders.load_encoder`, except that
    ``"thumbnail"`` is the ``thumbnail_levels``-band Laplacian pyramid of side
    ``encoder_image_size`` (default 8: bands of 4 and 8 px) rather than the single 16x16 thumbnail."""
    from ..encoders import load_encoder

    cfg = (config or ReachConfig()).validate()
    if name == "thumbnail" and cfg.thumbnail_levels > 1:
        from ..encoders.thumbnail import ThumbnailEncoder

        if weights:
            raise SplatplanError("the thumbnail encoder is weight-free: drop --encoder-weights")
        return ThumbnailEncoder(size=cfg.encoder_image_size or 8, levels=cfg.thumbnail_levels, device=device or "cpu")
    return load_encoder(name, weights=weights, device=device or "cpu", image_size=cfg.encoder_image_size)


def run_reach(
    robot: Robot | str,
    scene,
    target_image,
    *,
    config: ReachConfig | None = None,
    collision: bool = True,
    q0=None,
    encoder="thumbnail",
    encoder_weights: str | None = None,
    goal_camera_pose=None,
    renderer=None,
    device: str | None = "auto",
    progress=None,
) -> ReachResult:
    """Reach the view of ``target_image`` with the wrist camera (see the module docstring).

    Args:
        robot: a 7-DoF arm Robot or name ("panda").
        scene: a built-in name, a splat file or a :class:`TaskScene`.
        target_image: (H, W, 3) RGB in [0, 1]; any size (the encoder resizes it).
        config: :class:`ReachConfig`.
        collision: include the collision cost.
        q0: start configuration (default ``robot.q_default``).
        encoder: an Encoder or a :func:`~splatplan.encoders.load_encoder` name.
        encoder_weights: weights for a named encoder.
        goal_camera_pose: (4, 4) world <- camera of the target view, for the error numbers only
            (the controller never sees it).
        renderer: a :class:`~splatplan.render.SplatRenderer` of the scene's splats (made here if None).
        device: metric / renderer / encoder device.
        progress: optional callable(step, image_cost).
    """
    from ..planners.costs import UntilGoalCost
    from ..planners.dynamics import JointIntegrator
    from ..render import SplatRenderer
    from ..render.cameras import camera_pose_error, wrist_camera  # the renderer (Warp) loads on use, not with the config
    from ..robots import load_robot

    cfg = (config or ReachConfig()).validate()
    robot = load_robot(robot)
    ts = load_task_scene(scene, n_sigma=cfg.n_sigma, device=device, n_splats=cfg.n_splats)
    img = np.asarray(target_image, np.float32)
    if img.ndim != 3 or img.shape[-1] != 3 or not np.all(np.isfinite(img)):
        raise SplatplanError(f"target image must be a finite (H, W, 3) RGB array, got shape {img.shape}")
    enc = reach_encoder(encoder, encoder_weights, device or "cpu", cfg) if isinstance(encoder, str) else encoder
    q = robot.check_q(robot.q_default if q0 is None else q0).reshape(robot.dof).copy()
    if collision:
        check_start(robot, ts.checker, q)
    cam = wrist_camera(robot, cfg.image_size, cfg.fov_deg, cfg.camera_link)
    own = renderer is None
    rend = SplatRenderer(ts.splats, device) if own else renderer
    try:
        image_cost = cfg.image_cost(rend, cam, robot, enc, img)
        path_costs = cfg.joint_costs(robot)
        if collision:
            path_costs.insert(0, cfg.collision_cost(ts.checker, robot))
        vmax = cfg.velocity_bound(robot)
        mcfg = replace(cfg.mppi, u_min=tuple(-vmax), u_max=tuple(vmax), report_nominal=True)  # the nominal's raw image cost anneals the noise
        dyn = JointIntegrator(robot, velocity_limits=vmax)
        mppi = MPPI(dyn, None, mcfg, costs=[UntilGoalCost(path_costs), image_cost])
        search = route = None
        if collision and cfg.goal_search:  # the goal first (free goal state), then a collision-free path to it
            search = MPPI(dyn, None, mcfg, costs=[UntilGoalCost(cfg.joint_costs(robot)), image_cost])
            route = partial(_route, robot, ts.checker, cfg)
        run = GoalTimeMPC(mppi, cfg, vmax, "image_raw", search=search, route=route)
        views, view_every = [], max(1, cfg.mppi.horizon // max(cfg.n_views, 1))

        def on_step(s: int, q_s: np.ndarray, best: float) -> None:
            if progress is not None:
                progress(s, best)
            if cfg.n_views > 0 and s % view_every == 0:
                views.append((s, image_cost.render(q_s[None])[0]))

        t0 = time.perf_counter()
        states, trace = run.execute(q, on_step)
        elapsed = time.perf_counter() - t0
        final = _host(image_cost.render(states[-1][None])[0])
        views = [(s, _host(v)) for s, v in views]
    finally:
        if own:
            rend.close()
    traj = np.asarray(states)
    clearance, clearance_moving, source = run_clearance(robot, ts, traj)  # (every link's and the moving ones' minimum from one evaluation)
    li = robot.link_names.index(cfg.camera_link)
    cam_poses = robot.link_poses(traj)[:, li] @ cam.offset  # (S + 1, 4, 4) world <- camera
    pe = re = float("nan")
    if goal_camera_pose is not None:
        pe, re = camera_pose_error(cam_poses[-1], np.asarray(goal_camera_pose, np.float64))
    success = bool(np.isfinite(pe) and pe < cfg.position_tol and re < cfg.orientation_tol_deg and clearance > 0)
    return ReachResult(
        trajectory=traj,
        final_image=np.clip(final, 0.0, 1.0),
        views=views,
        camera_trace=cam_poses[:, :3, 3],
        translation_error_m=pe,
        rotation_error_deg=re,
        min_clearance_m=clearance,
        clearance_source=source,
        image_cost_trace=np.asarray(trace),
        iterations=run.iters,
        time_s=elapsed,
        collision_cost=bool(collision),
        encoder=enc.name,
        success=success,
        extra={"robot": robot.name, "scene": ts.name, "n_splats": len(ts.splats), "image_size": cfg.image_size, "n_samples": cfg.mppi.n_samples, "horizon": cfg.mppi.horizon,
               "plan_start_costs": run.start_costs, "route": run.route_outcome, "goal_search_costs": None if run.search_costs is None else [round(c, 4) for c in run.search_costs], "kept_goal_search": run.kept_search,
               # the moving links only: the Panda's fixed link0 sits 2.2 cm above the table whatever the arm does
               "min_clearance_moving_links_m": round(clearance_moving, 6)},
    )


def _route(robot: Robot, checker, cfg: ReachConfig, start: np.ndarray, goal: np.ndarray) -> np.ndarray | None:
    """A collision-free joint path (N, dof) from ``start`` to ``goal`` (RRT-Connect + shortcut on the
    task's checker, ``cfg.route_time_s``), or None when there is none in time (or an end collides)."""
    try:
        res = plan(checker, start, goal, robot=robot, refine=False, seed=cfg.mppi.seed, rrt_config=RRTConfig(time_limit_s=cfg.route_time_s))
    except PlanningError:
        return None
    return np.asarray(res.path, np.float64) if res.success else None


def _host(image) -> np.ndarray:
    """An image (numpy, or a torch tensor on any device) as a host numpy array."""
    return image.detach().cpu().numpy() if hasattr(image, "detach") else np.asarray(image)


