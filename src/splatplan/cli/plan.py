"""`splatplan plan`: batched RRT or RRT-Connect (+ refinement) for a robot, from a start to a goal
configuration. ``--planner auto`` (the default) runs RRT-Connect for every robot but a point and the
goal-biased RRT for a point (a sphere or ellipsoid that translates); ``--time-limit`` bounds the whole call, refinement included, and the
time split (sampling, nearest neighbours, collision, shortcut, refine) is printed.

Exit codes: 0 path found (written to ``--out``), 1 no path within the budget (one line on stderr;
an existing ``--out`` is kept unless ``--force``), 2 bad input.

Every length the user does not set (stride, edge resolution, goal tolerance, sampling box) is
derived from the scene and the robot; the values used are printed on one line. Configuration
vectors are comma lists of the robot's dofs and may start with a minus sign
(``--start -0.3,0,0.06``); an arm without ``--start`` starts from its home configuration.

The result file records its frame (robot spec, base pose, metric settings, scene path and sha256:
:mod:`splatplan.cli._results`), so ``view --plan``, ``check --plan`` and ``mpc --plan`` place the
robot where it was planned, and the path's clearance in metres
(:func:`~splatplan.planners.clearance.path_metric_clearance`: an estimate from the metric, a lower
bound on the distance to the nearest splat mean, less the n_sigma inflation).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import asdict, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import SplatplanError
from ..robots.builtin import DEFAULT_POINT_ROBOT, ROBOT_NAME_HELP
from ._results import frame_record, note
from ._common import (
    _load, add_base_pose_arg, add_command, add_config_args, add_device_arg, add_metric_args, add_seed_arg, add_terrain_args, allow_negative_values, config_from_args, float_arg,
    MAX_COORD, ground_robot_scene, metric_config_from_args, parse_base_pose, parse_numbers, robot_at, strict_float, unit_quaternion, write_json,
)  # fmt: skip

if TYPE_CHECKING:
    from ..robots.robot import Robot


#: the link ``--goal-pose`` places unless ``--ee-link`` names another
DEFAULT_EE_LINK = "panda_hand_tcp"

#: what the recorded clearance means (written beside it in the result file)
CLEARANCE_NOTE = ("estimate from the CollisionSplatting metric, (sqrt(min s2~) - 1) x the smallest semi-axis of the ellipsoid, minimised over "
                  "the path densified by step_m of robot motion: a lower bound on the distance from the robot's ellipsoids to the nearest "
                  "splat mean (opacity >= opacity_min), smaller by the n_sigma inflation (about n_sigma splat standard deviations); "
                  "at_least = farther than the metric looks; between samples it may dip by up to step_m / 2")


def parse_goal_pose(text: str, robot: Robot, link: str) -> np.ndarray:
    """'X,Y,Z,QW,QX,QY,QZ' -> (7,) with a unit quaternion (one-line errors). For arms: a robot that
    is only its moving base (go2, a point robot) has no link pose of its own to reach."""
    if robot.base != "fixed" and robot.dof == 3:
        raise SplatplanError(f"--goal-pose is for arms; {robot.name} takes --goal with its {robot.dof} dofs")
    if link not in robot.link_names:
        raise SplatplanError(f"--ee-link {link!r} is not a link of {robot.name} ({', '.join(robot.link_names[-4:])}, ...)")
    v = parse_numbers(text, "--goal-pose", "7 numbers X,Y,Z,QW,QX,QY,QZ", 7, None)
    if np.any(np.abs(v[:3]) > MAX_COORD):
        raise SplatplanError(f"--goal-pose {text!r}: the position X,Y,Z must be within +-{MAX_COORD:g}")
    v[3:] = unit_quaternion(v[3:], "--goal-pose", text)
    return v


def parse_config(text: str, robot: Robot, what: str) -> np.ndarray:
    """'a,b,c' -> (dof,) float64 configuration of ``robot`` (a one-line error otherwise)."""
    names = ",".join(robot.joint_names)
    try:
        v = np.asarray([strict_float(x) for x in str(text).split(",")], dtype=np.float64)
    except ValueError:
        raise SplatplanError(f"{what} {text!r}: expected {robot.dof} comma-separated numbers ({names}) for robot {robot.name}") from None
    if v.shape != (robot.dof,):
        raise SplatplanError(f"{what} {text!r}: robot {robot.name} has {robot.dof} dofs ({names}), got {v.size} number(s)")
    if not np.all(np.isfinite(v)):
        raise SplatplanError(f"{what} {text!r}: values must be finite")
    if np.any(np.abs(v) > MAX_COORD):
        raise SplatplanError(f"{what} {text!r}: values must be within +-{MAX_COORD:g}")
    return v


def _base_pose(args, robot: Robot) -> np.ndarray | None:
    """The (4, 4) world <- base pose --base-pose gives ``robot`` with a planar base's --height folded
    in (None for none): where _robot_for places it and what the result records as its base pose."""
    pose = parse_base_pose(args.base_pose)
    if args.height is not None and robot.base == "planar":
        pose = (np.eye(4) if pose is None else pose) @ np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, float(args.height)], [0, 0, 0, 1.0]])
    elif args.height is not None and not args.planar:
        raise SplatplanError("--height is the plane of --planar (or of a planar base such as go2); give --planar too (or drop --height)")
    return pose


def _robot_for(args) -> Robot:
    """The robot named by --robot, its base placed by --base-pose; a planar base drives in the plane
    of the floor frame given by --base-pose raised by --height (a robot that walks on terrain, go2
    or ``PATH.urdf:walking``, stands on it)."""
    from ..robots import load_robot

    if args.up is not None:
        raise SplatplanError(
            f"--up {args.up} was replaced by one frame vocabulary: align the scene once (splatplan scene align IN --up {args.up} --out OUT.ply, "
            "z up, floor at z = 0) and plan in it; --base-pose X,Y,Z[,QW,QX,QY,QZ] places the robot"
        )
    robot = load_robot(args.robot)
    return robot_at(args.robot, _base_pose(args, robot), robot=robot)


def _start(args, robot: Robot) -> np.ndarray:
    """--start, or an arm's home configuration (``robot.q_default``, as ``mpc`` starts) when not given."""
    if args.start is not None:
        return parse_config(args.start, robot, "--start")
    if robot.base != "fixed":
        raise SplatplanError(f"--start is required for {robot.name} (a moving base has no home in the scene): give its {robot.dof} dofs ({','.join(robot.joint_names)})")
    q = np.asarray(robot.q_default, dtype=np.float64).reshape(robot.dof).copy()
    note(f"no --start: {robot.name} starts from its home configuration {np.round(q, 4).tolist()}")
    return q


def _png_target(text: str | None) -> Path | None:
    """``--png``'s path, checked before any work: a PATH.png with a place to go (one line otherwise)."""
    if text is None:
        return None
    from .._files import output_target

    if Path(text).suffix.lower() != ".png":
        raise SplatplanError(f"--png {text}: expected a PATH.png")
    output_target(text)  # the one output rule: its folder exists, it is not a folder
    return Path(text)


def _write_png(png: Path, scene, robot: Robot, path: np.ndarray, title: str, trace_link: str | None) -> None:
    """The path's picture (:func:`splatplan.render.robot_overlay.path_figure`), written atomically."""
    from .._files import atomic_path
    from ..render.robot_overlay import path_figure

    fig = path_figure(scene, robot, path, title=title, trace_link=trace_link)
    with atomic_path(png) as tmp:
        fig.savefig(tmp, format="png", dpi=100)


def cmd_plan(args) -> int:
    from ..metric import CollisionChecker
    from ..planners import RefineConfig, RRTConfig, format_time_split, make_planner, plan

    out = Path(args.out)
    if out.suffix != ".json":
        raise SplatplanError(f"--out {args.out}: expected a .json path")
    if not out.parent.exists():
        raise SplatplanError(f"output folder {out.parent} does not exist")
    if args.planner.strip().lower().startswith("ompl:"):
        from ..planners.ompl_bridge import require_ompl

        require_ompl()  # the missing extra is named before any work
    png = _png_target(args.png)
    if args.ee_link is not None and args.goal_pose is None:
        raise SplatplanError("--ee-link names the link that --goal-pose places; give --goal-pose too (or drop --ee-link)")
    robot = _robot_for(args)
    base_pose = _base_pose(args, robot)  # as given (a ground robot's standing offset is the robot's own)
    start = _start(args, robot)
    if (args.goal is None) == (args.goal_pose is None):
        raise SplatplanError("give exactly one of --goal (a configuration) or --goal-pose X,Y,Z,QW,QX,QY,QZ (an arm's end-effector pose)")
    goal_pose = None if args.goal_pose is None else parse_goal_pose(args.goal_pose, robot, args.ee_link or DEFAULT_EE_LINK)
    goal = start.copy() if goal_pose is not None else parse_config(args.goal, robot, "--goal")
    rrt_cfg = config_from_args(args, RRTConfig, prefix="rrt_", time_limit_s=args.time_limit, seed=args.seed)
    if args.box is not None:
        lo, hi = (parse_config(b, robot, "--box") for b in args.box)
        rrt_cfg = replace(rrt_cfg, box_lo=tuple(lo), box_hi=tuple(hi))
    notes = []
    if args.planar:
        if robot.base == "planar":
            notes.append(f"{robot.name} moves in its base plane already")
        elif robot.is_point:
            axis = 2
            h = start[axis] if args.height is None else float(args.height)
            start[axis] = h
            if goal[axis] != h:
                notes.append(f"goal {'xyz'[axis]} set to the plane's {h:g}")
            goal[axis] = h
            frozen = tuple(sorted(set(rrt_cfg.frozen or ()) | {axis}))
            rrt_cfg = replace(rrt_cfg, frozen=frozen)
            if rrt_cfg.box_lo is not None and rrt_cfg.box_hi is not None:
                blo, bhi = list(rrt_cfg.box_lo), list(rrt_cfg.box_hi)
                blo[axis] = bhi[axis] = h
                rrt_cfg = replace(rrt_cfg, box_lo=tuple(blo), box_hi=tuple(bhi))
        else:
            raise SplatplanError(f"--planar is for point robots (sphere/ellipsoid) and planar bases (go2), not {robot.name}")
    rrt_cfg.validate()
    ref_cfg = config_from_args(args, RefineConfig, prefix="refine_", seed=args.seed)
    mcfg = metric_config_from_args(args)
    scene = _load(args.scene)
    terrain = None
    if robot.walks_on_terrain:  # a ground robot: the floor's splats are terrain (scenes/terrain.py)
        from ..scenes.terrain import TerrainConfig

        scene = ground_robot_scene(scene, args, mcfg.n_sigma)
        terrain = {"config": asdict(config_from_args(args, TerrainConfig, prefix="terrain_")), **scene.info.get("terrain", {})}
    frame = frame_record(args.robot, base_pose, args.scene, mcfg, terrain)
    checker = CollisionChecker(scene, device=args.device, config=mcfg)
    if goal_pose is not None:  # inverse kinematics: the collision-free solution nearest to the start
        from ..robots.ik import collision_free_ik

        goal = collision_free_ik(robot, checker, goal_pose[:3], goal_pose[3:], link=args.ee_link or DEFAULT_EE_LINK, near=start, seed=args.seed)
        notes.append(f"--goal-pose: IK goal configuration {np.round(goal, 4).tolist()}")
    ompl = args.planner.strip().lower().startswith("ompl:")
    planner = make_planner("auto" if ompl else args.planner, checker, rrt_cfg, robot=robot)
    settings = planner.settings(start, goal)  # an OMPL planner samples the same box at the same edge resolution
    name = args.planner.strip() if ompl else planner.name
    print(f"plan {robot.name} ({robot.dof} dofs, {robot.n_ellipsoids} ellipsoid(s)), {name}, n_sigma {mcfg.n_sigma:g}: {settings.summary()}")
    for note in notes + settings.notes:
        print(f"note: {note}", file=sys.stderr)
    res = plan(checker, start, goal, robot=robot, refine=args.refine, seed=args.seed, rrt_config=rrt_cfg, refine_config=ref_cfg, planner=name)
    split = res.info.get("time_split", {})
    refine_note = None
    if args.refine and not res.refined:  # why the path stayed as the RRT found it
        refine_note = res.info.get("refine_message") or ("no path to refine" if not res.success else "a path of one vertex has nothing to refine")
    clear = None
    if res.success:
        from ..planners.clearance import path_metric_clearance

        clear = path_metric_clearance(checker, robot, np.asarray(res.path))
    doc = {
        "success": bool(res.success),
        "robot": robot.name,
        "joint_names": list(robot.joint_names),
        "path": np.asarray(res.path).tolist(),
        "length": float(res.length) if np.isfinite(res.length) else None,  # null when no path
        "time_s": float(res.time_s),
        "n_nodes": int(res.n_nodes),
        "n_iters": int(res.n_iters),
        "refined": bool(res.refined),
        "refine_message": refine_note or res.info.get("refine_message"),  # why --refine kept the RRT path (null without --refine)
        "message": res.message,
        # the smallest metric clearance estimate over the densified path (m; see `clearance`), null when no path
        "clearance_m": None if clear is None else round(clear.clearance_m, 6),
        "clearance": None if clear is None else {**clear.to_json(), "note": CLEARANCE_NOTE},
        "frame": frame,
        "settings": res.info.get("settings"),
        "planner": name,
        "time_split": {k: float(v) for k, v in split.items()},
    }
    if not res.success:
        kept = out.exists() and not args.force
        if not kept:
            write_json(out, doc)
        tail = f"; kept the existing {out} (--force overwrites it)" if kept else f" -> {out}"
        print(f"splatplan: {res.message}{tail}", file=sys.stderr)
        print(f"time split: {format_time_split(split)}")
        return 1
    write_json(out, doc)
    if png is not None:
        ee = args.ee_link or DEFAULT_EE_LINK
        trace = ee if robot.base == "fixed" and ee in robot.link_names else None
        _write_png(png, scene, robot, np.asarray(res.path), f"{robot.name} in {Path(args.scene).name}, {name}", trace)
    print(f"path found: {len(res.path)} vertices, length {res.length:.4f}{' (refined)' if res.refined else ''}; "
          f"{res.n_nodes:,} nodes, {res.time_s:.3f} s -> {out}")  # fmt: skip
    if refine_note:
        print(f"not refined: {refine_note}")
    if png is not None:
        print(f"picture of the path (top and side views): {png}")
    if clear is not None:  # (a path was found: computed above)
        print(clear.summary())
    print(f"time split: {format_time_split(split)}")
    return 0


def register(sub, eval_sub) -> None:
    from ..planners import RefineConfig, RRTConfig

    s = add_command(sub, "plan", cmd_plan, "RRT / RRT-Connect (+ refinement) from a start to a goal configuration of a robot",
                    "Batched RRT or RRT-Connect (+ zeroth-order refinement) in the robot's configuration space. Exit codes: 0 path found, "
                    "1 no path within the budget (an existing --out is kept unless --force), 2 bad input. The result records its frame "
                    "(robot, base pose, metric settings, scene path and sha256), which view/check/mpc --plan reuse, and the path's "
                    "clearance in metres: the smallest metric estimate (sqrt(min s2~) - 1) x smallest semi-axis over the path densified "
                    "by a quarter of the robot's smallest semi-axis of motion, a lower bound on the distance to the nearest splat mean, "
                    "smaller by the n_sigma inflation (about n_sigma splat standard deviations; at n_sigma 0 the bound on the means alone).")  # fmt: skip
    allow_negative_values(s)
    s.add_argument("scene", metavar="SCENE")
    s.add_argument("--robot", default=DEFAULT_POINT_ROBOT, help=f"{ROBOT_NAME_HELP} (default {DEFAULT_POINT_ROBOT})")
    s.add_argument("--start", default=None, help="start configuration, comma list of the robot's dofs (X,Y,Z for point robots; a leading minus is fine); "
                   "default for an arm: its home configuration (required for other robots)")
    s.add_argument("--goal", default=None, help="goal configuration, comma list of the robot's dofs")
    s.add_argument("--goal-pose", default=None, help="arms: X,Y,Z,QW,QX,QY,QZ goal pose of --ee-link (metres, wxyz, world): the goal is the "
                   "collision-free inverse-kinematics solution nearest to the start")  # fmt: skip
    s.add_argument("--ee-link", default=None, help=f"the link --goal-pose places (default {DEFAULT_EE_LINK})")
    s.add_argument("--box", nargs=2, metavar=("LO", "HI"), help="sampling box corners, comma lists of the robot's dofs (default: "
                   "robust scene bounds padded by the robot size, joint limits for joints; lo == hi freezes a coordinate)")  # fmt: skip
    add_base_pose_arg(s)
    s.add_argument("--up", default=None, help=argparse.SUPPRESS)  # removed: say how to align instead
    s.add_argument("--planar", action="store_true", help="plan at a fixed height z: point robots keep z at "
                   "--height (default the start's); a planar base (go2) drives in the plane z = --height")  # fmt: skip
    s.add_argument("--height", type=float_arg(ge=-MAX_COORD, le=MAX_COORD), default=None, help="plane height z for --planar / a planar base such as go2, which stands on it (scene units; world z up, see `scene align`)")
    s.add_argument("--planner", default="auto", metavar="NAME", help="auto (rrt for a point robot, else rrtconnect) | rrt "
                   "(goal-biased batched RRT) | rrtconnect (batched bidirectional RRT-Connect) | ompl:NAME, an OMPL geometric planner on "
                   "the same checker (ompl:RRTConnect, ompl:RRTstar, ompl:BITstar, ompl:PRM, ...; needs the 'ompl' extra) (default auto)")  # fmt: skip
    s.add_argument("--time-limit", type=float_arg(gt=0, le=1e6), default=None, help="wall-clock budget of the whole call in seconds: search, shortcut and "
                   "--refine share it (default 10; same as --rrt-time-limit-s)")  # fmt: skip
    s.add_argument("--refine", action="store_true", help="zeroth-order refinement of the RRT path")
    add_seed_arg(s)
    s.add_argument("--force", action="store_true", help="overwrite an existing --out even when no path is found")
    add_device_arg(s)
    s.add_argument("--out", required=True, help="PATH.json")
    s.add_argument("--png", default=None, metavar="FILE.png", help="when a path is found, draw it: the robot's ellipsoids at several "
                   "configurations from start to goal over the opaque splat means (top and side views, coloured by height, metres)")  # fmt: skip
    add_metric_args(s)
    add_terrain_args(s)
    add_config_args(s, RRTConfig, prefix="rrt_", skip=("seed",), group="RRT options (RRTConfig; lengths in scene units of robot motion)")
    add_config_args(s, RefineConfig, prefix="refine_", skip=("seed",), group="refinement options (RefineConfig, with --refine)")
