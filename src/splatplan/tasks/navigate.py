"""Image-goal navigation (paper Sec. IV-B, E6): a quadruped explores, recognises the place a target
image was taken from, and drives there.

1. **Explore**: batched RRT in exploration mode (no goal) over the Go2's planar base grows
   collision-free nodes from the start (:func:`explore`); by default the yaw of the nodes is
   frozen at ``tree_yaw`` (the tree grows over x, y; see :class:`NavigateConfig`).
2. **Index**: the head camera's view at every node (thinned to one per ``index_spacing_m``), at
   ``n_headings`` evenly spaced headings, is rendered (batched) and encoded (:func:`build_view_index`).
3. **Retrieve**: the node and heading whose embedding is closest to the target image's
   (squared distance, the image cost of the paper) (:func:`~splatplan.encoders.view_index.retrieve`). A match whose best cost is
   not clearly below the typical cost (``best / median > weak_ratio``) is reported as **weak** and
   the robot does not drive unless asked to.
4. **Drive**: base MPPI with the collision cost (every body and leg ellipsoid) drives to the
   retrieved node given only its position (:func:`drive_to`), holding the tree's heading (a soft
   cost: the tree's edges were collision-checked at that heading). With ``follow_tree`` (default) the
   goal cost pulls towards a point ``lookahead_m`` ahead along the tree's branch to that node (the
   tree is the map the exploration built; a bare goal position leaves MPPI stuck behind walls
   between rooms); ``follow_tree=False`` is the bare setting.

Floor: the Go2's feet touch z = 0 in ``load_robot("go2")``; here the robot is
:func:`splatplan.tasks.base.load_go2` (feet lifted 4 cm, as in a trot's swing phase) and the metric
and the exact clearance use the scene **without the floor** (the terrain of
:mod:`splatplan.scenes.terrain`: floor-like splats with their mean within 5 cm of z = 0; the
analytic floor box);
renders use every splat.

Units: metres, radians; world frame z up; yaw about +z, 0 = looking along +x.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from .._config import NESTED_SKIP, bounded
from ..errors import SplatplanError
from ..encoders.view_index import ViewIndexTerms
from ..planners.costs import CollisionTerms
from ..planners.mppi import MPPIConfig
from ._common import TaskConfig, TaskScene, load_filtered_scene

if TYPE_CHECKING:
    from ..robots.robot import Robot
    from ..scenes.splats import Splats

__all__ = ["NavigateConfig", "NavScene", "DriveResult", "head_camera", "load_nav_scene", "explore", "build_view_index", "drive_to", "nav_robot"]


def _drive_mppi() -> MPPIConfig:
    """The drive's MPPI settings: K = 48, T = 16 steps of 0.1 s, 5 knots, commands within (0.6 m/s, 0.3 m/s, 1 rad/s)."""
    return MPPIConfig(n_samples=48, horizon=16, n_knots=5, dt=0.1, temperature=0.05, noise_sigma=(0.25, 0.15, 0.5), n_iters=1,
                      u_min=(-0.6, -0.3, -1.0), u_max=(0.6, 0.3, 1.0), report_nominal=False)  # fmt: skip


@dataclass
class NavigateConfig(TaskConfig, CollisionTerms, ViewIndexTerms, n_sigma=0.5, w_collision=5.0, w_hit=20.0, collision_s2_cap=2.0):
    # n_sigma 0.5: at 1 the apartment's large level-1 splats leave only 11% of random Go2 poses free against 39% by
    # the exact geometry (0.5: 28%, 0.5% missed); the drive's collision cost uses drive_n_sigma
    """Knobs of the image-goal navigation (exploration, retrieval, driving)."""

    #: splats of a built-in scene (fewer = faster renders); None = the scene's default
    n_splats: int | None = bounded(80_000, ge=1)
    #: start pose (x, y, yaw) of the exploration and of every drive
    start: tuple[float, float, float] = (-0.8, 0.3, 0.0)
    #: exploration sampling box lower corner (x, y) (m)
    box_lo: tuple[float, float] = (-3.9, -2.9)
    #: exploration sampling box upper corner (x, y) (m)
    box_hi: tuple[float, float] = (3.9, 2.9)
    #: nodes of the exploration tree
    tree_nodes: int = bounded(1200, ge=2)
    #: heading of every tree node (rad): the tree grows over (x, y) with the yaw frozen (views are
    #: rendered at every heading anyway, and a frozen yaw passes the doorways in walls x = const
    #: head-on); None = explore the yaw too (much slower: turning counts as motion)
    tree_yaw: float | None = 0.0
    #: RRT stride (largest edge, weighted configuration distance)
    tree_stride: float = bounded(0.5, gt=0)
    #: wall-clock cap of the exploration (s)
    tree_time_s: float = bounded(120.0, gt=0)
    #: largest motion of any ellipsoid point between collision checks along a tree edge (m)
    edge_resolution_m: float = bounded(0.06, gt=0)
    #: a match is weak when best cost / median cost over all views exceeds this
    weak_ratio: float = bounded(0.5, gt=0, le=1)
    #: the drive's MPPI settings (noise and bounds: vx m/s, vy m/s, wz rad/s; the noise seed is ``seed``)
    mppi: MPPIConfig = field(default_factory=_drive_mppi, metadata={NESTED_SKIP: ("seed",)})
    #: weight of the distance to the (carrot) goal, per metre per step
    w_goal: float = bounded(2.0, ge=0)
    #: weight of the heading term sum_t wrap(yaw_t - tree_yaw)^2 (the tree's edges were checked at
    #: that heading; 0 = free heading)
    w_yaw: float = bounded(1.0, ge=0)
    #: weight of the control effort
    w_control: float = bounded(0.01, ge=0)
    #: conservatism (n_sigma) of the drive's collision cost (1.0 closes the 0.9 m doorway for the Go2)
    drive_n_sigma: float = bounded(0.5, ge=0)
    #: follow the tree's branch to the retrieved node (False = only the node position)
    follow_tree: bool = True
    #: carrot distance ahead along the branch (m)
    lookahead_m: float = bounded(0.6, gt=0)
    #: reached when within this distance of the node (m)
    goal_tol_m: float = bounded(0.15, gt=0)
    #: MPC step budget of one drive
    max_steps: int = bounded(300, ge=1)
    #: seed (RRT sampler, MPPI noise)
    seed: int = bounded(0, ge=0)

    def check(self) -> None:
        if not all(lo < hi for lo, hi in zip(self.box_lo, self.box_hi)):
            raise SplatplanError(f"NavigateConfig.box_lo must be < box_hi on both axes, got {self.box_lo} and {self.box_hi}")



def nav_robot(robot: Robot | str | None = None):
    """The Go2 of the navigation task (:func:`splatplan.tasks.base.load_go2`) unless one is given."""
    if robot is not None and not isinstance(robot, str):
        return robot
    if robot in (None, "go2"):
        from .base import load_go2

        return load_go2()
    from ..robots import load_robot

    return load_robot(robot)


def head_camera(robot: Robot, cfg: NavigateConfig):
    """The Go2's head camera of ``cfg`` (:meth:`~splatplan.encoders.view_index.ViewIndexTerms.head_camera`)."""
    return cfg.head_camera(robot)


def build_view_index(robot: Robot, nav: NavScene, nodes: np.ndarray, encoder, renderer, cfg: NavigateConfig):
    """The :class:`~splatplan.encoders.view_index.ViewIndex` of the tree's ``nodes`` (N, 3) under ``cfg``."""
    cfg.validate()
    return cfg.index_views(robot, nodes, encoder, renderer)


@dataclass
class NavScene:
    """The scene twice: every splat for rendering, the floor-free scene for the metric and clearance."""

    render_splats: Splats
    task: TaskScene  # checker and analytic geometry without the floor


def floor_mask(splats, height: float = 0.05) -> np.ndarray:
    """(N,) bool: the floor's splats, the terrain of :mod:`splatplan.scenes.terrain` (floor at
    z = 0, step ``height``, normals within 25 deg of z) restricted to means above -``height``."""
    from ..scenes.terrain import terrain_mask

    return terrain_mask(splats, 0.0, height, n_sigma=0.0, max_tilt_deg=25.0) & (np.asarray(splats.means)[:, 2] > -height)


def load_nav_scene(scene="apartment", cfg: NavigateConfig | None = None, device: str | None = "auto", seed: int = 0) -> NavScene:
    """A built-in scene name (or a splat file) -> :class:`NavScene` (floaters filtered)."""
    from ..metric import CollisionChecker

    cfg = (cfg or NavigateConfig()).validate()
    name = str(scene)
    splats, gt = load_filtered_scene(name, n_splats=cfg.n_splats, seed=seed)
    floor = floor_mask(splats)
    metric_splats = splats.subset(np.flatnonzero(~floor))
    if gt is not None:
        gt = gt.select(np.array([lab != "floor" for lab in gt.labels]))
    checker = CollisionChecker(metric_splats, n_sigma=cfg.n_sigma, device=device)
    return NavScene(splats, TaskScene(name, metric_splats, checker, gt))


def explore(robot: Robot, nav: NavScene, cfg: NavigateConfig):
    """Exploration-mode RRT from ``cfg.start``: returns the :class:`~splatplan.planners.PlanResult`
    (``tree_nodes`` (N, 3) x, y, yaw; ``tree_parents`` (N,))."""
    from ..planners import RRT, RRTConfig

    cfg.validate()
    start = np.asarray(cfg.start, np.float64).copy()
    ylo, yhi = (-np.pi, np.pi) if cfg.tree_yaw is None else (float(cfg.tree_yaw), float(cfg.tree_yaw))
    if cfg.tree_yaw is not None:
        start[2] = float(cfg.tree_yaw)
    rcfg = RRTConfig(
        batch_size=64, stride=cfg.tree_stride, edge_resolution=cfg.edge_resolution_m, max_nodes=cfg.tree_nodes, time_limit_s=cfg.tree_time_s, seed=cfg.seed, shortcut=False,
        box_lo=(cfg.box_lo[0], cfg.box_lo[1], ylo), box_hi=(cfg.box_hi[0], cfg.box_hi[1], yhi),
    )  # fmt: skip
    return RRT(nav.task.checker, rcfg, robot=robot).plan(start, None)


@dataclass
class DriveResult:
    """One drive: executed states (S + 1, 3), reached flag, final distance to the goal (m),
    smallest exact clearance over the densified path (m), time, steps."""

    states: np.ndarray
    reached: bool
    final_distance_m: float
    min_clearance_m: float
    clearance_source: str
    time_s: float
    steps: int
    message: str = ""


def drive_to(robot: Robot, nav: NavScene, goal_xy, cfg: NavigateConfig, *, start=None, branch: np.ndarray | None = None, progress=None) -> DriveResult:
    """Base MPPI with the collision cost from ``start`` (default ``cfg.start``) to ``goal_xy``.

    Args:
        goal_xy: (2,) the retrieved node's position (m).
        branch: (P, 2+) tree path ending at the goal, followed with a carrot when ``cfg.follow_tree``.
    """
    from ..planners import MPPI
    from ..planners.costs import ControlEffortCost, GoalPoseCost, StateCost
    from ..planners.dynamics import PlanarBase
    from ..planners.route import carrot, wrap_angle
    from ._common import check_start, run_clearance

    goal = np.asarray(goal_xy, np.float64).reshape(-1)[:2]
    x = np.asarray(cfg.start if start is None else start, np.float64).reshape(3).copy()
    check_start(robot, nav.task.checker, x)
    path = np.asarray(branch, np.float64)[:, :2] if (branch is not None and cfg.follow_tree) else np.stack([x[:2], goal])
    if np.linalg.norm(path[-1] - goal) > 1e-9:
        path = np.vstack([path, goal])
    dyn = PlanarBase(robot)
    goal_cost = GoalPoseCost(None, position=goal, state_dims=(0, 1), position_weight=cfg.w_goal, terminal_factor=2.0)
    drive_checker = nav.task.checker.with_config(n_sigma=cfg.drive_n_sigma)
    costs = [
        cfg.collision_cost(drive_checker, robot),
        goal_cost,
        ControlEffortCost(cfg.w_control),
    ]
    if cfg.w_yaw > 0 and cfg.tree_yaw is not None:
        yaw0 = float(cfg.tree_yaw)
        costs.append(StateCost(lambda s: wrap_angle(s[..., 2] - yaw0) ** 2, weight=cfg.w_yaw, name="heading"))
    mppi = MPPI(dyn, None, replace(cfg.mppi, seed=cfg.seed), costs=costs)
    states = [x.copy()]
    prog = 0
    t0 = time.perf_counter()
    reached = False
    for step in range(cfg.max_steps):
        dist = float(np.linalg.norm(x[:2] - goal))
        if progress is not None:
            progress(step, dist)
        if dist < cfg.goal_tol_m:
            reached = True
            break
        target, prog = carrot(path, x[:2], cfg.lookahead_m, prog) if cfg.follow_tree else (goal, 0)
        goal_cost.position = np.asarray(target, np.float64)
        u, _ = mppi.step(x)
        x = dyn.rollout(x, u[None, None, :], cfg.mppi.dt)[0, 0]
        x[2] = float(wrap_angle(x[2]))
        states.append(x.copy())
    elapsed = time.perf_counter() - t0
    traj = np.asarray(states)
    clearance, _, source = run_clearance(robot, nav.task, traj)
    dist = float(np.linalg.norm(traj[-1, :2] - goal))
    reached = reached or dist < cfg.goal_tol_m
    msg = "" if reached else f"not within {cfg.goal_tol_m} m of the goal after {cfg.max_steps} MPC steps ({dist:.2f} m left)"
    return DriveResult(traj, bool(reached), dist, clearance, source, elapsed, len(traj) - 1, msg)
