"""Visual reaching (paper Sec. IV-A, E5): drive a 7-DoF arm so that its wrist camera sees a target
image, with MPPI over joint-velocity B-splines and the terminal image cost.

Camera: a pinhole camera at the Panda's ``panda_hand_tcp`` frame (OpenCV axes = the TCP axes: it
looks along the gripper's z axis), :func:`wrist_camera`.

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

Schedule (shrinking horizon, so that the goal time stays fixed): the initial plan starts
``plan_starts`` times from zero velocity with different noise seeds, ``plan_start_iters`` MPPI
iterations each, then ``plan_start_refine`` goal-state refinements (below; the starts' local
minima are compared, not their progress), and continues the lowest-cost one; the first MPC step runs
``plan_iters`` MPPI iterations in all over the horizon T, in chunks of ``plan_chunk`` between which the
knot noise anneals on image-cost progress (``noise_cost_ref``), then ``refine_plan_iters``
goal-state refinements (:class:`GoalRefiner`: samples that move only the plan's state at the goal
time, with a learned covariance: near the goal the image cost is a narrow valley, camera
translation traded against rotation, where isotropic knot noise only finds tiny improvements);
each later MPC step starts with ``refine_iters`` refinements. Each MPC step applies the
first control, shifts the knots (warm start; a constant velocity offset puts the plan's goal-time
state back where it was, ``keep_goal_state``) and runs ``iters_per_step`` iterations at
``track_temperature`` (nearly greedy: the nominal is always a sample, so it is only replaced by a
better one), the image now rendered at step ``T - 1 - s`` of the rollout after ``s`` executed
steps. After T steps the arm is where the plan ended. K = 32, T = 48, 8 knots, dt = 0.05 s and
temperature 0.1 follow the paper's authors' example; images are 64x64 here (224x224 in the paper).

The controller sees the target image only: no goal pose, configuration or collision information
enters the without-collision run (the start is an IK solution of a fixed camera pose; the goals
are chosen collision-free by the study, as in the paper).

Units: metres, radians, seconds; world frame z up (the tabletop scene's).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from .._config import NESTED_SKIP, bounded, check_order
from ..errors import SplatplanError
from ..planners.goal_refiner import GoalRefiner
from ..planners.costs import StridedCollisionTerms
from ..planners.mppi import MPPI, MPPIConfig
from ._common import TaskConfig, TaskScene, check_start, load_task_scene, moving_clearance, trajectory_clearance

__all__ = ["BEHIND_WALL", "START_CAMERA", "ReachConfig", "ReachResult", "camera_pose_error", "make_reach_goals", "reach_encoder", "reach_start", "run_reach", "wrist_camera"]


def _reach_mppi() -> MPPIConfig:
    """The reach's MPPI settings (the paper's authors' example): K = 32, T = 48, 8 knots, dt = 0.05 s, temperature 0.1."""
    return MPPIConfig(n_samples=32, horizon=48, n_knots=8, dt=0.05, temperature=0.1, noise_sigma=0.25, n_iters=1)


@dataclass
class ReachConfig(TaskConfig, StridedCollisionTerms, n_sigma=1.0, w_collision=0.1, w_hit=10.0, collision_s2_cap=1.3, collision_stride=2):
    """Knobs of :func:`run_reach` (MPPI over joint-velocity B-splines with the image cost)."""

    #: MPPI settings (noise_sigma in rad/s; the horizon is the executed steps too: a shrinking horizon; the iterations
    #: per step come from the schedule below, the control bounds from velocity_scale)
    mppi: MPPIConfig = field(default_factory=_reach_mppi, metadata={NESTED_SKIP: ("u_min", "u_max", "n_iters", "report_nominal")})
    #: knot noise at the last MPC step as a fraction of noise_sigma (linear in the remaining
    #: horizon: finer exploration as the goal time approaches); 1 = constant noise
    noise_final: float = bounded(0.3, ge=0)
    #: noise annealing on image-cost progress: the knot noise is further scaled by
    #: clip(sqrt(c / noise_cost_ref), noise_min_scale, 1), c = raw image cost of the current plan
    #: (the pose error grows like sqrt(c) near the goal); 0 = off
    noise_cost_ref: float = bounded(4.0, ge=0)
    #: lower bound of that scale
    noise_min_scale: float = bounded(0.03, ge=0, le=1)
    #: with annealing, the initial plan runs in chunks of this many iterations (annealed in between)
    plan_chunk: int = bounded(5, ge=1)
    #: MPPI temperature while the arm moves (after the initial plan; None = temperature): a small one
    #: keeps the plan's nominal (always among the samples) unless a sample beats it, so the warm-started
    #: plan does not drift through the weighted averaging of one iteration per step
    track_temperature: float | None = bounded(0.02, gt=0)
    #: after each warm-start shift, offset the knots so that the plan's state at the goal time stays
    #: where the plan had it (the least-squares shift alone drifts it over the run)
    keep_goal_state: bool = True
    #: MPPI iterations before the first control is applied
    plan_iters: int = bounded(60, ge=1)
    #: multi-start initial plan: this many plans (noise seeds seed, seed + 1, ...) each run
    #: plan_start_iters iterations from zero velocity; the lowest-cost one continues (1 = one start)
    plan_starts: int = bounded(3, ge=1)
    #: MPPI iterations of each start of a multi-start initial plan (counted within plan_iters)
    plan_start_iters: int = bounded(30, ge=1)
    #: goal-state refinement iterations ending each start of a multi-start plan, before the starts
    #: are compared (a look-alike view and the goal's basin then differ in cost; 0 = compare as is)
    plan_start_refine: int = bounded(10, ge=0)
    #: MPPI iterations per later MPC step
    iters_per_step: int = bounded(2, ge=1)
    #: the last final_steps MPC steps run final_iters iterations each (fine convergence at the goal)
    final_steps: int = bounded(0, ge=0)
    #: MPPI iterations per step over the last final_steps steps
    final_iters: int = bounded(3, ge=1)
    #: goal-state refinement (GoalRefiner): iterations per MPC step whose K samples move
    #: only the plan's state at the goal time, by joint offsets (a constant velocity offset on every
    #: knot); the cheapest sample (the plan itself among them) is kept
    refine_iters: int = bounded(1, ge=0)
    #: refinement iterations after the initial plan (before the first control)
    refine_plan_iters: int = bounded(20, ge=0)
    #: initial std of those joint offsets (rad); it grows x refine_grow after an improving
    #: iteration and shrinks x refine_shrink otherwise, within [refine_sigma_min, refine_sigma]
    refine_sigma: float = bounded(0.05, ge=0)
    #: lower bound of the refinement std (rad)
    refine_sigma_min: float = bounded(0.002, ge=0)
    #: growth of the refinement std after an improvement
    refine_grow: float = bounded(1.5, ge=1)
    #: shrink of the refinement std after an iteration without improvement
    refine_shrink: float = bounded(0.6, gt=0, le=1)
    #: joint velocity bound as a fraction of the robot's velocity limits
    velocity_scale: float = bounded(0.6, gt=0, le=1)
    #: rendered image side (pixels, square)
    image_size: int = bounded(64, ge=1)
    #: horizontal field of view of the wrist camera (degrees)
    fov_deg: float = bounded(70.0, gt=0, lt=180)
    #: render background grey level: a mid grey keeps views of empty space from scoring like dark
    #: image regions (with a black background the weight-free thumbnail rewards looking away)
    background: float = bounded(0.5, ge=0, le=1)
    #: weight of the image cost
    w_image: float = bounded(1.0, ge=0)
    #: side the encoder resizes images to (None = its default: 8 for the reach thumbnail pyramid, 224 for EfficientNet / DINOv2)
    encoder_image_size: int | None = bounded(None, ge=1)
    #: bands of the thumbnail encoder's Laplacian pyramid (1 = the single 16x16 thumbnail)
    thumbnail_levels: int = bounded(2, ge=1)
    #: image cost scored as log(1 + c / image_log_eps) (0 = the raw distance c): MPPI then weighs
    #: relative progress, so it keeps converging near the goal where raw differences shrink
    image_log_eps: float = bounded(0.01, ge=0)
    #: compare L2-normalised features (cosine distance in [0, 4]): one cost scale for every encoder,
    #: so the image cost neither swamps nor vanishes beside the collision cost
    normalize_features: bool = True
    #: weight of the empty-view term mean(1 - alpha) of the rendered view (0 = image cost only)
    w_empty: float = bounded(1.0, ge=0)
    #: weight of the global-embedding distance inside the image cost
    w_global: float = bounded(1.0, ge=0)
    #: weight of the mean patch-token distance inside the image cost (0 = off; needs tokens)
    w_patch: float = bounded(0.0, ge=0)
    #: weight of the control effort sum |qdot|^2 dt
    w_control: float = bounded(0.01, ge=0)
    #: weight of the joint-limit penalty
    w_limits: float = bounded(100.0, ge=0)
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


def wrist_camera(robot, image_size: int = 64, fov_deg: float = 70.0, link: str = "panda_hand_tcp"):
    """The wrist camera: a :class:`~splatplan.render.MountedCamera` at ``link`` (identity offset:
    the camera looks along the link's z axis, image x along link x)."""
    from ..render import MountedCamera, intrinsics_from_fov

    cam = MountedCamera(link, np.eye(4), intrinsics_from_fov(fov_deg, image_size, image_size), image_size, image_size)
    cam._link_index(robot)
    return cam


def camera_pose_error(t: np.ndarray, t_goal: np.ndarray) -> tuple[float, float]:
    """(translation error m, rotation error deg) between camera poses world <- camera (4, 4)."""
    pe = float(np.linalg.norm(t[:3, 3] - t_goal[:3, 3]))
    c = 0.5 * (np.trace(t_goal[:3, :3].T @ t[:3, :3]) - 1.0)
    return pe, float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


#: The studies' start view: the wrist camera above the bin, just behind its front wall, looking straight down
#: (world frame, metres; the rotation of the Panda's default TCP: x along world x, z down).
START_CAMERA = (np.array([0.56, 0.0, 0.22]), np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]))
#: Camera region counted as "behind the wall": inside the bin (x, y) and below the front wall's top.
BEHIND_WALL = (np.array([0.46, -0.28, -0.09]), np.array([0.84, 0.28, 0.15]))


def reach_start(robot, camera_link: str = "panda_hand_tcp") -> np.ndarray:
    """The studies' start configuration: IK of :data:`START_CAMERA` nearest ``q_default``."""
    from ..robots.ik import solve_ik
    from ..scenes.splats import rotmat_to_quat

    p, r = START_CAMERA
    q, pe, re = solve_ik(robot, p, rotmat_to_quat(r), link=camera_link, n_seeds=8, n_iters=150, seed=0, q_init=robot.q_default)
    ok = (pe < 0.002) & (re < np.radians(1.0))
    if not np.any(ok):
        raise SplatplanError(f"the reach start view is not reachable by {robot.name} (IK error {pe[0] * 100:.1f} cm)")
    q = q[ok]
    return q[int(np.argmin(np.sum((q - robot.q_default) ** 2, axis=1)))]


def _scaled_camera(camera, width: int):
    """``camera`` (a MountedCamera) at ``width`` pixels wide, same field of view and aspect."""
    from ..render import MountedCamera

    if camera.width == width:
        return camera
    s = width / camera.width
    k = np.asarray(camera.K, np.float64).copy()
    k[:2] *= s
    return MountedCamera(camera.link_name, camera.offset, k, width, max(1, round(camera.height * s)))


def make_reach_goals(
    robot, scene: TaskScene, renderer, camera, *, n: int = 5, q_start=None, spread: float = 0.35, n_behind: int = 2, margin_m: float = 0.02,
    min_move_m: float = 0.05, max_move_m: float = 0.15, max_turn_deg: float = 30.0, n_candidates: int = 1024, seed: int = 0,
    behind_spread: float = 0.45, behind_max_move_m: float = 0.2, min_contrast: float = 0.12, view_check_px: int = 64,
) -> list[dict]:
    """Random reachable, collision-free goal configurations near ``q_start`` whose wrist view is
    informative, ``n_behind`` of them with the camera behind the bin's front wall (:data:`BEHIND_WALL`).

    Candidates ``q_start + U(-spread, spread)^7`` (clipped to the limits) are kept when every link
    ellipsoid clears the exact geometry by ``margin_m``, the metric finds no collision, there is no
    self-collision, the camera moves ``min_move_m``..``max_move_m`` from the start and turns by at
    most ``max_turn_deg`` (half the candidates use ``behind_spread`` and, behind the wall only,
    ``behind_max_move_m``: reaching behind the wall takes a longer move), and the view
    is filled by the scene (alpha > 0.98) with contrast (pixel std > ``min_contrast``: a plain view of
    floor and wall is ambiguous for any encoder). The view is judged at most ``view_check_px``
    pixels wide (same field of view, scaled intrinsics): at 224 px single edge pixels of a full
    view fall below the alpha bar, and goals for large images would not exist. Goals are then picked far apart from each other (greedy farthest point in camera position).

    Returns:
        [{"name", "q" (7,), "camera_pose" (4, 4) world <- camera, "clearance_m", "behind_wall"}].
    """
    rng = np.random.default_rng(seed)
    q_start = np.asarray(robot.q_default if q_start is None else q_start, np.float64)
    lim = np.asarray(robot.joint_limits, np.float64)
    half = n_candidates // 2
    sp = np.concatenate([np.full(half, spread), np.full(n_candidates - half, behind_spread)])[:, None]
    q = np.clip(q_start + rng.uniform(-1.0, 1.0, (n_candidates, robot.dof)) * sp, lim[:, 0] + 0.05, lim[:, 1] - 0.05)
    li = camera._link_index(robot)
    t_start = robot.link_poses(q_start)[li] @ camera.offset
    t = robot.link_poses(q)[:, li] @ camera.offset  # (M, 4, 4)
    move = np.linalg.norm(t[:, :3, 3] - t_start[:3, 3], axis=1)
    turn = np.degrees(np.arccos(np.clip(0.5 * (np.einsum("ij,kij->k", t_start[:3, :3], t[:, :3, :3]) - 1.0), -1.0, 1.0)))
    lo_b, hi_b = BEHIND_WALL
    in_b = np.all((t[:, :3, 3] > lo_b) & (t[:, :3, 3] < hi_b), axis=1)
    keep = (move > min_move_m) & (move < np.where(in_b, behind_max_move_m, max_move_m)) & (turn < max_turn_deg)
    q, t = q[keep], t[keep]
    if scene.analytic is not None and len(q):
        c, qu, ax = robot.ellipsoids(q)
        clear = scene.analytic.ellipsoid_clearance(c, qu, ax).min(axis=-1)
    else:
        clear = np.full(len(q), np.inf)
    keep = clear > margin_m
    if len(q):
        keep &= ~np.asarray(scene.checker.collides_robot(robot, q)).any(axis=-1) & ~np.asarray(robot.self_collision(q))
    q, t, clear = q[keep], t[keep], clear[keep]
    if len(q):
        check_cam = _scaled_camera(camera, min(camera.width, view_check_px))
        res = check_cam.render(renderer, robot, q)
        rgb, alpha = np.asarray(res.rgb), np.asarray(res.alpha)
        keep = (alpha.reshape(len(q), -1).min(axis=1) > 0.98) & (rgb.reshape(len(q), -1).std(axis=1) > min_contrast)
        q, t, clear = q[keep], t[keep], clear[keep]
    lo, hi = BEHIND_WALL
    behind = np.all((t[:, :3, 3] > lo) & (t[:, :3, 3] < hi), axis=1)
    chosen: list[int] = []

    def pick(pool: np.ndarray, count: int) -> None:  # greedy farthest point in camera position
        for _ in range(max(count, 0)):
            cand = [int(i) for i in pool if int(i) not in chosen]
            if not cand:
                return
            if not chosen:
                chosen.append(cand[int(np.argmax(clear[cand]))])
            else:
                d = np.min(np.linalg.norm(t[cand][:, None, :3, 3] - t[chosen][None, :, :3, 3], axis=-1), axis=1)
                chosen.append(cand[int(np.argmax(d))])

    pick(np.flatnonzero(behind), min(n_behind, n))
    pick(np.arange(len(q)), n - len(chosen))
    return [
        {"name": f"goal{j}" + ("_behind_wall" if behind[i] else ""), "q": q[i], "camera_pose": t[i], "clearance_m": float(clear[i]), "behind_wall": bool(behind[i])}
        for j, i in enumerate(chosen)
    ]


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
    robot,
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
    from ..render import SplatRenderer
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
        run = _ReachRun(robot, ts, rend, cam, enc, img, cfg, collision)
        t0 = time.perf_counter()
        states, trace, views = run.execute(q, progress)
        elapsed = time.perf_counter() - t0
        final = _host(run.image_cost.render(states[-1][None])[0])
        views = [(s, _host(v)) for s, v in views]
    finally:
        if own:
            rend.close()
    traj = np.asarray(states)
    clearance, source, _ = trajectory_clearance(robot, ts, traj)
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
               "plan_start_costs": run.start_costs,
               # the moving links only: the Panda's fixed link0 sits 2.2 cm above the table whatever the arm does
               "min_clearance_moving_links_m": round(float(moving_clearance(robot, ts, traj)), 6)},
    )


def _host(image) -> np.ndarray:
    """An image (numpy, or a torch tensor on any device) as a host numpy array."""
    return image.detach().cpu().numpy() if hasattr(image, "detach") else np.asarray(image)


class _ReachRun:
    """The schedule of :func:`run_reach` (module docstring) on one :class:`~splatplan.planners.MPPI`:
    multi-start initial plan, goal-state refinement, shrinking-horizon tracking. Counts the MPPI
    iterations in ``iters``; ``start_costs`` are the multi-start costs."""

    def __init__(self, robot, ts: TaskScene, renderer, camera, encoder, target: np.ndarray, cfg: ReachConfig, collision: bool) -> None:
        from ..planners.costs import ControlEffortCost, JointLimitCost, UntilGoalCost
        from ..planners.dynamics import JointIntegrator
        from ..planners.image_cost import ImageCost

        self.cfg, self.robot = cfg, robot
        self.vmax = cfg.velocity_scale * np.asarray(robot.velocity_limits, np.float64)
        self.dyn = JointIntegrator(robot, velocity_limits=self.vmax)
        self.image_cost = ImageCost(renderer, camera, robot, encoder, target, weight=cfg.w_image, w_global=cfg.w_global, w_patch=cfg.w_patch, background=(cfg.background,) * 3,
                                    w_empty=cfg.w_empty, log_eps=cfg.image_log_eps, normalize=cfg.normalize_features)  # fmt: skip
        path_costs = [ControlEffortCost(cfg.w_control), JointLimitCost(robot, weight=cfg.w_limits, margin=0.05)]
        if collision:
            path_costs.insert(0, cfg.collision_cost(ts.checker, robot))
        mcfg = replace(cfg.mppi, u_min=tuple(-self.vmax), u_max=tuple(self.vmax), report_nominal=True)  # the nominal's raw image cost anneals the noise
        self.mppi = MPPI(self.dyn, None, mcfg, costs=[UntilGoalCost(path_costs), self.image_cost])
        self.refiner = self._new_refiner()
        self.iters, self.start_costs = 0, []

    def anneal(self, c: float) -> float:
        """Noise scale from the raw image cost ``c`` of the current plan."""
        cfg = self.cfg
        return float(np.clip(np.sqrt(c / cfg.noise_cost_ref), cfg.noise_min_scale, 1.0)) if cfg.noise_cost_ref > 0 else 1.0

    def plan_chunk(self, q: np.ndarray, n: int, scale: float):
        """n MPPI iterations at noise scale ``scale``, nothing executed (the warm-start shift is
        undone); returns the step's info and the noise scale annealed on the plan's image cost."""
        self.mppi.set_noise_scale(scale)
        _, info = self.mppi.step(q, n_iters=n)
        self.mppi.reset(info.nominal_knots)
        return info, self.anneal(float(np.min(info.nominal_values["image_raw"])))

    def _new_refiner(self, *key: int) -> GoalRefiner:
        cfg = self.cfg
        rng = np.random.default_rng([cfg.mppi.seed, 1, *key])
        return GoalRefiner(self.robot.dof, cfg.mppi.n_samples, cfg.refine_sigma, sigma_min=cfg.refine_sigma_min, grow=cfg.refine_grow, shrink=cfg.refine_shrink, rng=rng)

    def refine(self, q: np.ndarray, n: int, m: int, goal_step: int | None = None) -> float:
        """n refinement iterations of the plan's state at the goal time (m controls ahead): offset d_k
        moves it through the knot offset d_k / (m dt) (the B-spline basis sums to 1). Returns the
        total cost of the kept plan (inf when n = 0)."""
        kept = np.inf
        for _ in range(n):
            d = self.refiner.sample()  # (K, 7) rad, row 0 = 0 (the plan itself)
            samples = np.clip(self.mppi.knots[None] + d[:, None, :] / (m * self.cfg.mppi.dt), -self.vmax, self.vmax)  # (K, n_knots, 7)
            total = self.mppi.evaluate(q, samples, goal_step).total
            b = self.refiner.update(d, total)
            self.mppi.reset(samples[b])
            kept = float(total[b])
        return kept

    def initial_plan(self, q: np.ndarray, chunk: int) -> tuple[int, float]:
        """The multi-start plan (when ``plan_starts`` > 1) and the rest of ``plan_iters`` but the
        last chunk; returns the iterations done on the kept plan and its noise scale."""
        cfg, mppi = self.cfg, self.mppi
        done, scale = 0, 1.0
        if cfg.plan_starts > 1:  # several short plans from zero velocity, each with its own noise; the best continues
            n0 = min(cfg.plan_start_iters, cfg.plan_iters - 1)
            starts = []
            for j in range(cfg.plan_starts):
                mppi.reset(rng=cfg.mppi.seed + j)
                sc, left = 1.0, n0
                while left > 0:
                    n = min(chunk, left)
                    info, sc = self.plan_chunk(q, n, sc)
                    left -= n
                cost, knots = info.nominal_cost, info.nominal_knots
                if cfg.plan_start_refine > 0:  # compare the starts' local minima, not their progress
                    self.refiner = self._new_refiner(j)
                    cost, knots = self.refine(q, cfg.plan_start_refine, cfg.mppi.horizon), mppi.knots.copy()
                starts.append((cost, j, knots, sc, mppi.rng, self.refiner))
            self.start_costs = [round(float(e[0]), 4) for e in starts]
            _, _, knots, scale, rng, self.refiner = min(starts, key=lambda e: (e[0], e[1]))
            mppi.reset(knots, rng=rng)
            done = n0  # the chosen start's iterations; the other starts' are extra
            self.iters += n0 * (cfg.plan_starts - 1) + cfg.plan_start_refine * cfg.plan_starts
        while cfg.plan_iters - done > chunk:
            _, scale = self.plan_chunk(q, chunk, scale)
            done += chunk
        self.iters += done
        if cfg.refine_plan_iters > 0:
            self.refine(q, cfg.refine_plan_iters, cfg.mppi.horizon)
            self.iters += cfg.refine_plan_iters
        return done, scale

    def execute(self, q: np.ndarray, progress=None) -> tuple[list, list, list]:
        """Plan, then execute the T steps; returns the states, the per-step raw image cost of the
        plan, and the kept wrist views [(step, image)]."""
        cfg, mppi, t_len = self.cfg, self.mppi, self.cfg.mppi.horizon
        states, trace, views = [q.copy()], [], []
        view_every = max(1, t_len // max(cfg.n_views, 1))
        chunk = max(1, cfg.plan_chunk) if cfg.noise_cost_ref > 0 else cfg.plan_iters  # the noise anneals on progress between chunks
        done, scale = self.initial_plan(q, chunk)
        for s in range(t_len):
            goal = t_len - 1 - s  # the goal time stays at T; the rollout's tail beyond it is never executed
            if s > 0 and cfg.refine_iters > 0:
                self.refine(q, cfg.refine_iters, t_len - s, goal)
                self.iters += cfg.refine_iters
            n_iters = cfg.plan_iters - done if s == 0 else (cfg.final_iters if s >= t_len - cfg.final_steps else cfg.iters_per_step)
            lam = cfg.mppi.temperature if s == 0 or cfg.track_temperature is None else cfg.track_temperature
            mppi.set_noise_scale(scale, cfg.noise_final + (1.0 - cfg.noise_final) * (t_len - s) / t_len)
            u, info = mppi.step(q, n_iters=n_iters, temperature=lam, goal_step=goal)
            self.iters += n_iters
            q = self.dyn.rollout(q, u[None, None, :], cfg.mppi.dt)[0, 0]
            states.append(q.copy())
            if cfg.keep_goal_state and s + 1 < t_len:
                # the least-squares warm-start shift moves the plan's state at the goal time; a constant
                # velocity offset (the B-spline basis sums to 1) puts it back where the plan had it
                m = t_len - 1 - s  # controls from the new state up to the goal time
                shifted = self.dyn.rollout(q, mppi.spline(mppi.knots[None]), cfg.mppi.dt)[0, m - 1]
                mppi.reset(mppi.knots + (info.nominal_states[goal] - shifted)[: mppi.du] / (m * cfg.mppi.dt))
            best = float(np.min(info.nominal_values["image_raw"]))  # raw image cost of the updated nominal plan
            trace.append(best)
            scale = self.anneal(best)
            if progress is not None:
                progress(s, best)
            if cfg.n_views > 0 and s % view_every == 0:
                views.append((s, self.image_cost.render(q[None])[0]))
        return states, trace, views
