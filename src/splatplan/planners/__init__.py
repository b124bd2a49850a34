"""Planners stage: batched RRT and RRT-Connect, MPPI over B-spline controls, zeroth-order path refinement.

Everything here talks to the scene only through a :class:`~splatplan.metric.CollisionChecker`
(``query`` for costs, ``collides`` for edge checks), so it runs on any checker backend/device.

    from splatplan.planners import plan
    res = plan(checker, (0, 0, 0.06), (0.45, 0.1, 0.06), robot=load_robot("sphere:0.015"))   # a point robot
    res = plan(checker, q0, q1, robot=load_robot("panda"))                                   # joint space
    res.success, res.path, res.length, res.info["settings"]
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from typing import TYPE_CHECKING

from ..errors import PlanningError, SplatplanError

from .bspline import UniformBSpline, bspline_basis, bspline_eval, fit_bspline, knot_vector, resample_polyline
from .costs import CollisionCost, CollisionTerms, ControlEffortCost, Cost, CostValue, GoalPoseCost, JointLimitCost, JointVelocityTerms, Rollout, StateCost, StridedCollisionTerms, TerminalCost, UntilGoalCost, evaluate_costs, total_cost
from .image_cost import ImageCost
from .dynamics import Dynamics, DynamicsModel, HolonomicPoint, JointIntegrator, PlanarBase, yaw_to_quat
from .metrics import clearance, d_min, densify_path, smoothness
from .mppi import MPPI, CostWeights, Evaluation, GaussianKnots, MPPIConfig, MPPIInfo, SamplingStrategy
from .refine import RefineConfig, RefineResult, refine_path
from .robot_links import as_robot, robot_collides, robot_query
from .rrt_connect import RRTConnect
from .edges import EdgeChecker, edge_points, edge_samples, shortcut_path
from .escape import Escape, escape_endpoint
from .rrt import RRT, robust_scene_box
from .rrt_types import PlanResult, RRTConfig, RRTSettings, path_length

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..robots.robot import Robot
    from ..scenes.margin import SplatMargin

__all__ = [
    "CollisionCost",
    "CollisionTerms",
    "StridedCollisionTerms",
    "ControlEffortCost",
    "Cost",
    "CostValue",
    "CostWeights",
    "Evaluation",
    "GaussianKnots",
    "SamplingStrategy",
    "UntilGoalCost",
    "evaluate_costs",
    "Dynamics",
    "DynamicsModel",
    "EdgeChecker",
    "Escape",
    "escape_endpoint",
    "GoalPoseCost",
    "ImageCost",
    "JointLimitCost",
    "JointVelocityTerms",
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
    "RRTConnect",
    "PLANNERS",
    "format_time_split",
    "make_planner",
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
    "yaw_to_quat",
]


#: planner names for :func:`plan` / ``splatplan plan --planner`` ("auto": rrt for a point robot,
#: the paper's planner for it; rrtconnect for every other robot: arms and planar bases)
PLANNERS = ("auto", "rrt", "rrtconnect")


def make_planner(name: str, checker: CollisionChecker, config: RRTConfig | None = None, *, robot: Robot | str):
    """The planner called ``name`` (see :data:`PLANNERS`) for ``robot`` (a Robot or a name for
    :func:`~splatplan.robots.load_robot`) on ``checker``: an object with
    ``plan(start, goal, deadline=None) -> PlanResult`` and ``settings(start, goal)``.

    Raises:
        SplatplanError: an unknown name (the message lists the known ones).
    """
    key = str(name).strip().lower().replace("-", "").replace("_", "")
    if key not in PLANNERS:
        raise SplatplanError(f"unknown planner {name!r}: choose one of {', '.join(PLANNERS)}")
    robot = as_robot(robot)
    if key == "auto":
        key = "rrt" if robot.is_point else "rrtconnect"
    cls = RRTConnect if key == "rrtconnect" else RRT
    return cls(checker, config, robot=robot)


def plan(
    checker: CollisionChecker,
    start,
    goal,
    *,
    robot: Robot | str,
    refine: bool = True,
    seed: int = 0,
    rrt_config: RRTConfig | None = None,
    refine_config: RefineConfig | None = None,
    planner: str = "auto",
    margin: SplatMargin | None = None,
    escape_robot: Robot | str | None = None,
) -> PlanResult:
    """Plan a collision-free path for a robot: RRT or RRT-Connect (+ shortcut) (+ refinement).

    ``rrt_config.time_limit_s`` bounds the **whole call**: search, shortcut and refinement share
    one deadline (a refinement cut short keeps the shortcut path).

    Args:
        checker: a :class:`~splatplan.metric.CollisionChecker` (its ``n_sigma`` sets the conservatism).
        start: (D,) start configuration (a point robot: its centre, scene units, world frame;
            an arm: joint angles; a planar base: x, y, yaw).
        goal: (D,) goal configuration.
        robot: (required) a :class:`~splatplan.robots.Robot` or a name for
            :func:`~splatplan.robots.load_robot`; a point robot is ``load_robot("sphere:R")``
            (:data:`~splatplan.robots.DEFAULT_POINT_ROBOT` is the studies' sphere).
        refine: run :func:`refine_path` on the found path (kept only if collision-free).
        seed: seeds the RRT sampler and the refinement noise (overrides the configs' seeds).
        rrt_config: :class:`RRTConfig` (default: RRTConfig(): scene-scaled lengths, 10 s).
            Give ``box_lo``/``box_hi`` with equal z (or ``frozen=(2,)``) to plan in a plane.
        refine_config: :class:`RefineConfig` (default: RefineConfig()).
        planner: one of :data:`PLANNERS`: "auto" (the goal-biased RRT for a point robot,
            RRT-Connect for every other robot: arms and planar bases), "rrt" or "rrtconnect"; or
            "ompl:NAME", an OMPL geometric planner on the same checker, box, edge resolution and
            time limit (:func:`~splatplan.planners.ompl_bridge.plan_ompl`; the ``ompl`` extra;
            ``refine`` and ``seed`` do not apply there).
        margin: the scene's :class:`~splatplan.scenes.SplatMargin` (:func:`~splatplan.scenes.margin_for`),
            with ``robot`` the robot's own model: the planner grows the robot by ``margin.margin``,
            checks edges at ``margin.edge_resolution`` (or the finer ``rrt_config.edge_resolution``)
            and leaves an endpoint that the margin blocks by a short straight segment checked at a
            finer resolution with the smaller margin that keeps the same guarantee
            (:func:`~splatplan.planners.escape_endpoint`); ``info["escape"]`` describes the
            segments. None (default): ``robot`` is used as given (grow it yourself).
        escape_robot: with ``margin``, a tighter model of the same robot for the escape segments'
            check (:func:`~splatplan.planners.escape_endpoint`); None: ``robot``.

    Returns:
        :class:`PlanResult`; ``path_rrt`` holds the raw tree path, ``path`` the final one,
        ``refined`` says whether the refinement was accepted, ``info["length_rrt"]`` the length
        of the shortcut RRT path, ``info["settings"]`` the RRT values used (derived or given),
        ``info["planner"]`` the planner that ran, ``info["time_split"]`` the seconds spent
        sampling, in nearest neighbours, collision checks (of the search), shortcut, refine and
        other (the rest); they sum to ``time_s``.

    Raises:
        PlanningError: start or goal in collision (with ``margin``: even for the finest endpoint
            check), outside the scene bounds or the sampling box.
        SplatplanError: an unknown planner name, no robot, or ``margin`` with an OMPL planner or
            a coarser ``rrt_config.edge_resolution`` than the margin assumes.
    """
    if planner.startswith("ompl:"):
        from .ompl_bridge import plan_ompl

        if margin is not None or escape_robot is not None:
            raise SplatplanError("plan: margin= (endpoint escapes) applies to the library's planners, not OMPL's; grow the robot yourself")
        return plan_ompl(checker, start, goal, robot=robot, name=planner, time_limit_s=None, rrt_config=rrt_config)
    t0 = time.perf_counter()
    cfg = replace(rrt_config or RRTConfig(), seed=seed)
    deadline = None if cfg.time_limit_s is None else t0 + cfg.time_limit_s
    escapes: list[Escape] = []
    if margin is not None:
        base = as_robot(robot)
        cfg = _margin_config(cfg, margin)
        rrt = make_planner(planner, checker, cfg, robot=base.inflated(float(margin.margin)))
        t_esc = time.perf_counter()
        escapes = _escapes(checker, base, rrt, margin, start, goal, seed, None if escape_robot is None else as_robot(escape_robot))
        t_esc = time.perf_counter() - t_esc
        start, goal = escapes[0].path[-1], escapes[1].path[-1]
        rrt._checked_free = {np.asarray(q, dtype=np.float64).reshape(-1).tobytes() for q in (start, goal)}  # (free for its geometry: the escapes checked them)
    else:
        rrt = make_planner(planner, checker, cfg, robot=robot)
    res = rrt.plan(start, goal, deadline=deadline)
    res.info["length_rrt"] = res.length
    res.info["path_shortcut"] = res.path.copy()
    t_ref = time.perf_counter()
    if refine and res.success and len(res.path) >= 2:
        rcfg = replace(refine_config or RefineConfig(), seed=seed)
        ref = refine_path(checker, res.path, config=rcfg, robot=rrt.robot, deadline=deadline)
        res.info["refine_message"] = ref.message
        if ref.accepted:
            res.path = ref.path
            res.length = path_length(ref.path, rrt.geometry.distance_scale())
            res.refined = True
    t_end = time.perf_counter()
    if escapes:
        _join_escapes(res, escapes, rrt.geometry.distance_scale())
    res.time_s = time.perf_counter() - t0
    split = dict(res.info.get("time_split", {}))
    split.pop("other", None)
    split["refine"] = t_end - t_ref
    if escapes:
        split["escape"] = t_esc
    split["other"] = max(0.0, res.time_s - sum(split.values()))
    res.info["time_split"] = split
    res.info["time_limit_s"] = cfg.time_limit_s
    return res


def _margin_config(cfg: RRTConfig, margin: SplatMargin) -> RRTConfig:
    """``cfg`` at the margin's edge resolution (or its own finer one)."""
    from ..scenes.margin import SplatMargin

    if not isinstance(margin, SplatMargin):
        raise SplatplanError(f"plan: margin must be a SplatMargin (splatplan.scenes.margin_for), got {type(margin).__name__}")
    r = float(margin.edge_resolution)
    if cfg.edge_resolution is None:
        return replace(cfg, edge_resolution=r)
    if cfg.edge_resolution > r * (1 + 1e-9):
        raise SplatplanError(f"plan: rrt_config.edge_resolution {cfg.edge_resolution:.4g} is coarser than the margin's {r:.4g}; its guarantee needs r or finer")
    return cfg


def _escapes(checker, base: Robot, planner, margin: SplatMargin, start, goal, seed: int, escape_robot: Robot | None = None) -> list[Escape]:
    """Each endpoint's :class:`Escape` (``planner``: the search's, on the robot grown by the margin:
    its geometry is reused, its sampling box holds the escape configurations)."""
    geometry = planner.geometry
    if goal is None:
        raise PlanningError("plan: margin= needs a goal")
    sq, gq = (base.check_q(np.asarray(x, dtype=np.float64).reshape(-1)) for x in (start, goal))
    st = planner.settings(sq, gq)  # the sampling box the search will use (given or derived)
    box = (st.box_lo, st.box_hi)
    kw = {"geometry": geometry, "box": box, "escape_robot": escape_robot}
    es = escape_endpoint(checker, base, sq, margin, toward=gq, seed=seed, what="start", **kw)
    eg = escape_endpoint(checker, base, gq, margin, toward=sq, seed=seed + 1, what="goal", **kw)
    return [es, eg]


def _join_escapes(res: PlanResult, escapes: list[Escape], w) -> None:
    """Put the escape segments on the path's ends (start's first, goal's reversed last), count their
    checks and describe them in ``info["escape"]``."""
    es, eg = escapes
    res.info["escape"] = {name: {"escaped": e.escaped, "divisor": e.divisor, "margin_m": e.margin, "edge_resolution_m": e.resolution,
                                 "displacement_m": e.displacement, "n_configs": e.n_configs, "n_sigma": e.n_sigma}
                          for name, e in (("start", es), ("goal", eg))}  # fmt: skip
    res.info["n_configs"] = int(res.info.get("n_configs", 0)) + es.n_configs + eg.n_configs
    if not res.success:
        return
    res.path = np.vstack([es.path[:-1], res.path, eg.path[::-1][1:]])
    if res.info.get("path_shortcut") is not None:
        res.info["path_shortcut"] = np.vstack([es.path[:-1], res.info["path_shortcut"], eg.path[::-1][1:]])
    if res.path_rrt is not None:
        res.path_rrt = np.vstack([es.path[:-1], res.path_rrt, eg.path[::-1][1:]])
    res.length = path_length(res.path, w)


def format_time_split(split: dict) -> str:
    """One line: 'sampling 0.01 s, nearest 0.00 s, collision 0.84 s, ...' (the order of ``split``)."""
    return ", ".join(f"{k} {v:.3f} s" for k, v in split.items())
