"""Planners stage: batched RRT, MPPI over B-spline controls, zeroth-order path refinement.

Everything here talks to the scene only through a :class:`~splatplan.metric.CollisionChecker`
(``query`` for costs, ``collides`` for edge checks), so it runs on any checker backend/device.

    from splatplan.planners import plan
    res = plan(checker, start=(0, 0, 0.06), goal=(0.45, 0.1, 0.06))            # sphere r = 0.015
    res = plan(checker, start=q0, goal=q1, robot=load_robot("panda"))           # joint space
    res.success, res.path, res.length, res.info["settings"]
"""

from __future__ import annotations

import time
from dataclasses import replace

from ..errors import SplatplanError
from .bspline import UniformBSpline, bspline_basis, bspline_eval, fit_bspline, knot_vector, resample_polyline
from .costs import CollisionCost, ControlEffortCost, Cost, GoalPoseCost, JointLimitCost, Rollout, StateCost, TerminalCost, total_cost
from .image_cost import ImageCost
from .dynamics import Dynamics, HolonomicPoint, JointIntegrator, PlanarBase, sphere_links, yaw_to_quat
from .metrics import clearance, d_min, densify_path, smoothness
from .mppi import MPPI, MPPIConfig, MPPIInfo
from .refine import RefineConfig, RefineResult, refine_path
from .robot_links import LinkGeometry, as_robot, robot_collides, robot_query
from .rrt import RRT, EdgeChecker, PlanResult, RRTConfig, RRTSettings, edge_points, edge_samples, path_length, robust_scene_box, shortcut_path

__all__ = [
    "CollisionCost",
    "ControlEffortCost",
    "Cost",
    "Dynamics",
    "EdgeChecker",
    "GoalPoseCost",
    "ImageCost",
    "JointLimitCost",
    "LinkGeometry",
    "Rollout",
    "RRTSettings",
    "StateCost",
    "TerminalCost",
    "as_robot",
    "edge_samples",
    "robot_collides",
    "robot_query",
    "robust_scene_box",
    "total_cost",
    "HolonomicPoint",
    "JointIntegrator",
    "MPPI",
    "MPPIConfig",
    "MPPIInfo",
    "PlanResult",
    "PlanarBase",
    "RRT",
    "RRTConfig",
    "RefineConfig",
    "RefineResult",
    "UniformBSpline",
    "bspline_basis",
    "bspline_eval",
    "clearance",
    "d_min",
    "densify_path",
    "edge_points",
    "fit_bspline",
    "knot_vector",
    "path_length",
    "plan",
    "refine_path",
    "resample_polyline",
    "shortcut_path",
    "smoothness",
    "sphere_links",
    "yaw_to_quat",
]


def plan(
    checker,
    start,
    goal,
    radius: float = 0.015,
    refine: bool = True,
    seed: int = 0,
    rrt_config: RRTConfig | None = None,
    refine_config: RefineConfig | None = None,
    robot=None,
    planner: str = "rrt",
) -> PlanResult:
    """Plan a collision-free path for a robot: batched RRT (+ shortcut) (+ refinement).

    Args:
        checker: a :class:`~splatplan.metric.CollisionChecker` (its ``n_sigma`` sets the conservatism).
        start: (D,) start configuration (a point robot: its centre, scene units, world frame;
            an arm: joint angles; a planar base: x, y, yaw).
        goal: (D,) goal configuration.
        radius: shortcut for ``robot="sphere:<radius>"`` (scene units) when ``robot`` is None.
        refine: run :func:`refine_path` on the found path (kept only if collision-free).
        seed: seeds the RRT sampler and the refinement noise (overrides the configs' seeds).
        rrt_config: :class:`RRTConfig` (default: RRTConfig(): scene-scaled lengths, 10 s).
            Give ``box_lo``/``box_hi`` with equal z (or ``frozen=(2,)``) to plan in a plane.
        refine_config: :class:`RefineConfig` (default: RefineConfig()).
        robot: a :class:`~splatplan.robots.Robot` or a name for :func:`~splatplan.robots.load_robot`.
        planner: "rrt" (ours) or "ompl:NAME", an OMPL geometric planner on the same checker, box,
            edge resolution and time limit (:func:`~splatplan.planners.ompl_bridge.plan_ompl`;
            the ``ompl`` extra; ``refine`` and ``seed`` do not apply there).

    Returns:
        :class:`PlanResult`; ``path_rrt`` holds the raw tree path, ``path`` the final one,
        ``refined`` says whether the refinement was accepted, ``info["length_rrt"]`` the length
        of the shortcut RRT path, ``info["settings"]`` the RRT values used (derived or given).

    Raises:
        PlanningError: start or goal in collision, outside the scene bounds or the sampling box.
    """
    if planner.startswith("ompl:"):
        from .ompl_bridge import plan_ompl

        return plan_ompl(checker, start, goal, robot=robot, name=planner, time_limit_s=None, radius=radius, rrt_config=rrt_config)
    if planner != "rrt":
        raise SplatplanError(f"unknown planner {planner!r}: 'rrt' or 'ompl:NAME' (e.g. ompl:RRTConnect)")
    t0 = time.perf_counter()
    cfg = replace(rrt_config or RRTConfig(), seed=seed)
    rrt = RRT(checker, cfg, radius=radius, robot=robot)
    res = rrt.plan(start, goal)
    res.info["length_rrt"] = res.length
    res.info["path_shortcut"] = res.path.copy()
    if refine and res.success and len(res.path) >= 2:
        rcfg = replace(refine_config or RefineConfig(), seed=seed)
        ref = refine_path(checker, res.path, config=rcfg, robot=rrt.robot)
        res.info["refine_message"] = ref.message
        if ref.accepted:
            res.path = ref.path
            res.length = path_length(ref.path, rrt.geometry.distance_scale())
            res.refined = True
    res.time_s = time.perf_counter() - t0
    return res
