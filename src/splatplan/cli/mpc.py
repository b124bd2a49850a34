"""`splatplan mpc` (arm reaching / quadruped driving under MPPI) and the studies `eval arm`, `eval base`.

``mpc --plan PATH.json`` starts where a ``splatplan plan`` result starts and heads where it ends
(go2: the plan is the route it tracks; panda: the goal is the end-effector pose of the plan's last
configuration), with the robot, base pose and scene the result records unless flags give others.
The result.json records its frame like ``plan``'s (:mod:`splatplan.cli._results`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from ..errors import SplatplanError
from ..robots.builtin import DEFAULT_MODEL, PANDA_MODELS
from ._results import check_scene, fill_robot, frame_record, note, read_plan
from ._common import (
    MAX_COORD, _out_dir, add_base_pose_arg, atomic_dir, move_into, signals_deferred, parse_numbers, unit_quaternion, add_config_args, add_device_arg, add_seed_arg, check_device, config_from_args, float_arg, parse_base_pose, robot_at,
    write_json,
)  # fmt: skip

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..robots.robot import Robot


def _floats(text: str, n: int, what: str, form: str) -> np.ndarray:
    v = parse_numbers(text, what, f"{n} numbers {form}", n, None)
    if np.any(np.abs(v[:3]) > MAX_COORD):
        raise SplatplanError(f"{what} {text!r}: positions must be within +-{MAX_COORD:g}")
    return v


#: the built-in task `mpc` runs for each --robot choice (the name's part before any ":MODEL")
TASK_OF_ROBOT = {"panda": "arm", "go2": "base"}


def straight_line_blocked(robot: Robot, checker: CollisionChecker, start, goal_xy, step_m: float = 0.05, n_yaws: int = 1) -> bool:
    """Whether the planar base collides somewhere on the straight segment from ``start`` (x, y, yaw) to
    ``goal_xy`` at each of ``n_yaws`` fixed headings (the bearing to the goal, which the goal term
    faces, and its turns by 2 pi / n_yaws; positions every ``step_m``): then MPPI, given only the
    goal, would have to find a detour or a sequence of turns by itself, and `mpc` plans a route first."""
    start = np.asarray(start, np.float64)
    g = np.asarray(goal_xy, np.float64)
    n = max(2, int(np.ceil(np.linalg.norm(g - start[:2]) / step_m)) + 1)
    xy = start[:2] + (g - start[:2]) * np.linspace(0.0, 1.0, n)[:, None]  # (n, 2)
    bearing = float(np.arctan2(g[1] - start[1], g[0] - start[0]))
    yaws = bearing + 2 * np.pi * np.arange(n_yaws) / n_yaws  # (Y,)
    q = np.concatenate([np.c_[xy, np.full(n, y)] for y in yaws])  # (Y n, 3)
    hit = np.asarray(checker.collides_robot(robot, q)).any(axis=-1).reshape(n_yaws, n)
    return bool(hit.any(axis=1).all())


#: the --robot values mpc takes
MPC_ROBOTS = ("panda", *(f"panda:{m}" for m in PANDA_MODELS), "go2")


def _box_xy(args) -> tuple[np.ndarray, np.ndarray] | None:
    """go2 --box LO HI: X,Y or X,Y,YAW corners (the yaw part is ignored: the base turns freely) -> (lo (2,), hi (2,))."""
    if args.box is None:
        return None
    lo, hi = (_floats(b, 2 if len(b.split(",")) == 2 else 3, "--box", "X,Y or X,Y,YAW")[:2] for b in args.box)
    if np.any(hi <= lo):
        raise SplatplanError(f"--box {args.box[0]} {args.box[1]}: the corner LO must be below HI in x and y")
    return lo, hi


def cmd_mpc(args) -> int:
    from ..tasks._common import base_terrain, load_task_scene
    from ..tasks.plot import plot_run

    plan_q, frame = read_plan(args.plan) if args.plan is not None else (None, None)
    fill_robot(args, frame)
    if args.robot is None:
        raise SplatplanError("--robot is required (panda or go2), or --plan PATH.json of a plan that records it")
    if args.robot not in MPC_ROBOTS:
        raise SplatplanError(f"--robot {args.robot}: mpc runs {', '.join(MPC_ROBOTS)}" + (f" (from --plan {args.plan})" if frame is not None else ""))
    if args.scene is None and frame is not None and frame.scene is not None:
        args.scene = frame.scene.get("path") or frame.scene.get("builtin")
        note(f"scene {args.scene} from --plan {args.plan}")
    elif args.scene is not None:
        check_scene(args.scene, frame)
    out = _out_dir(args.out)
    collision = not args.no_collision
    tag = "" if collision else " [--no-collision: collision cost OFF]"
    task = TASK_OF_ROBOT.get(args.robot.partition(":")[0])
    if task is None:  # argparse choices keep this unreachable
        raise SplatplanError(f"unknown robot {args.robot!r}: panda or go2")
    go2_only = {"route": args.route, "no_route": args.no_route, "route_time": args.route_time is not None, "goal": args.goal is not None}
    if task == "arm":
        given = [f"--{k.replace('_', '-')}" for k, v in go2_only.items() if v]
        if given:
            raise SplatplanError(f"{given[0]} is for --robot go2 only (panda takes --goal-pose)")
    elif args.goal_pose is not None:
        raise SplatplanError("--goal-pose is for --robot panda only (go2 takes --goal X,Y)")
    if task == "arm" and args.box is not None:
        raise SplatplanError("--box is for --robot go2 (an arm's joints are bounded by their limits)")
    box = _box_xy(args)
    if args.route and args.no_route:
        raise SplatplanError("--route and --no-route contradict each other; give one")
    route_time = 60.0 if args.route_time is None else args.route_time
    if task == "arm":
        from ..tasks.arm import ArmConfig, run_arm

        cfg = config_from_args(args, ArmConfig, "arm_")
        cfg = replace(cfg, mppi=replace(cfg.mppi, seed=args.seed))
        robot = robot_at(args.robot, parse_base_pose(args.base_pose))
        _plan_fits(plan_q, robot, args.plan)
        if args.goal_pose is None and plan_q is None:
            raise SplatplanError("--robot panda needs --goal-pose X,Y,Z,QW,QX,QY,QZ (metres, wxyz) or --plan PATH.json")
        if args.goal_pose is not None:
            gp = _floats(args.goal_pose, 7, "--goal-pose", "X,Y,Z,QW,QX,QY,QZ")
            gp[3:] = unit_quaternion(gp[3:], "--goal-pose", args.goal_pose)
        else:  # the end-effector pose of the plan's last configuration
            from ..scenes.splats import rotmat_to_quat

            assert plan_q is not None  # (checked above)

            t = robot.link_poses(plan_q[-1:])[0, robot.link_names.index(cfg.ee_link)]  # (4, 4) world <- ee
            gp = np.concatenate([t[:3, 3], np.asarray(rotmat_to_quat(t[None, :3, :3]), np.float64).reshape(4)])
            note(f"goal pose {np.round(gp, 4).tolist()} of {cfg.ee_link} at the last configuration of --plan {args.plan}")
        scene = args.scene or "tabletop"
        q0: np.ndarray | None
        if args.start is not None:
            q0 = _floats(args.start, robot.dof, "--start", f"with {robot.dof} joint values")
        else:
            q0 = None if plan_q is None else plan_q[0].copy()
        ts = load_task_scene(scene, n_sigma=cfg.n_sigma, device=args.device)  # once: the run and the figure share it
        res = run_arm(robot, ts, gp[:3], gp[3:], config=cfg, collision=collision, q0=q0, device=args.device)
        kind = "arm"
    else:  # the base task's Go2
        from ..planners.route import plan_route
        from ..tasks.base import START, BaseConfig, load_go2, run_base

        from ..tasks.base import base_box

        cfg = config_from_args(args, BaseConfig, "base_")
        cfg = replace(cfg, mppi=replace(cfg.mppi, seed=args.seed))
        robot = robot_at("go2", parse_base_pose(args.base_pose), robot=load_go2())
        _plan_fits(plan_q, robot, args.plan)
        if args.goal is None and plan_q is None:
            raise SplatplanError("--robot go2 needs --goal X,Y (metres) or --plan PATH.json")
        if args.goal is not None:
            g = _floats(args.goal, 2, "--goal", "X,Y")
        else:
            assert plan_q is not None  # (checked above)
            g = plan_q[-1, :2].copy()
        scene = args.scene or "apartment"
        default = np.asarray(START, np.float64) if scene == "apartment" else np.zeros(3)  # the origin lies in the apartment's x = 0 wall
        default = default if plan_q is None else plan_q[0].copy()
        start = default if args.start is None else _floats(args.start, 3, "--start", "X,Y,YAW")
        ts = load_task_scene(scene, n_sigma=cfg.n_sigma, device=args.device, terrain=base_terrain(cfg))
        route = None
        lo, hi = base_box(ts, robot, box)
        inside = bool(np.all(g >= lo[:2]) and np.all(g <= hi[:2]))  # else run_base says so
        if inside and plan_q is not None and not args.no_route and not args.route:  # the plan is the route
            route = plan_q
            print(f"tracking the {len(plan_q)}-vertex path of --plan {args.plan} (--no-route: goal only, --route: plan a new route)")
        want = inside and route is None and (args.route or (not args.no_route and collision and straight_line_blocked(robot, ts.checker, start, g)))
        if want:
            if not args.route:
                print(f"the straight line from {start[:2].round(2).tolist()} to {g.round(2).tolist()} is blocked facing the goal: planning an SE(2) route first (--no-route: goal only)")
            route = plan_route(robot, ts.checker, start, g, time_budget_s=route_time, seed=args.seed, box=(lo[:2], hi[:2]))
            if route is None:
                print(f"no SE(2) route from {start[:2].round(2).tolist()} to {g.round(2).tolist()} within {route_time:g} s (try a larger --route-time)")
                return 1
        res = run_base(robot, ts, g, start=start, config=cfg, collision=collision, route=route, box=box, device=args.device)
        kind = "base"
    d = res.to_json()
    terrain = ts.splats.info.get("terrain") if kind == "base" else None
    d["frame"] = frame_record(args.robot, parse_base_pose(args.base_pose), scene, ts.checker.config, terrain)
    fig = plot_run(robot, ts, res, kind=kind)
    with atomic_dir(out) as tmp:  # result.json and motion.png appear together or not at all
        write_json(tmp / "result.json", d)
        fig.savefig(tmp / "motion.png", format="png", dpi=100)
        with signals_deferred():  # two renames: a signal between them would split the pair
            move_into(tmp / "result.json", out / "result.json")
            move_into(tmp / "motion.png", out / "motion.png")
    print(
        f"{robot.name} on {scene}{tag}: {'reached' if res.success else 'NOT reached'}; final position error {res.final_position_error_m * 100:.2f} cm; "
        f"min clearance {res.min_clearance_m * 100:.2f} cm ({res.clearance_source}); {res.steps_per_s:.2f} MPC steps/s over {res.time_s:.1f} s"
    )
    print(f"wrote {out / 'result.json'} and {out / 'motion.png'}{tag}")
    return 0 if res.success else 1


def _plan_fits(plan_q: np.ndarray | None, robot: Robot, path: str | None) -> None:
    """A --plan path must be of the robot's dofs (one line otherwise)."""
    if plan_q is not None and plan_q.shape[1] != robot.dof:
        raise SplatplanError(f"--plan {path}: its path has {plan_q.shape[1]} coordinates per vertex, {robot.name} has {robot.dof} ({', '.join(robot.joint_names)})")


def cmd_eval(args) -> int:
    """``eval arm`` / ``eval base``: run(config) -> result, report(result, out)."""
    import importlib

    mod = importlib.import_module(f"splatplan.eval.{args.study}")
    cls = mod.ArmStudyConfig if args.study == "arm" else mod.BaseStudyConfig
    cfg = config_from_args(args, cls, base=cls.quick_config() if args.quick else cls())
    cfg = replace(cfg, device=check_device(cfg.device))  # auto -> cuda:0 or cpu, as every --device
    out = _out_dir(args.out)
    res = mod.run(cfg)
    written = mod.report(res, out)
    print(mod.markdown(res).rstrip())
    print(f"\nwrote {', '.join(str(p) for p in written)}")
    return 0


def register(sub, eval_sub) -> None:
    from ..tasks.arm import ArmConfig
    from ..tasks.base import BaseConfig

    s = sub.add_parser("mpc", help="MPPI with the collision cost: Panda reaching (tabletop) or Go2 driving (apartment)")
    s.add_argument("--robot", default=None, metavar="{" + ",".join(MPC_ROBOTS) + "}",
                   help=f"panda (7-DoF arm, the {DEFAULT_MODEL} collision model; panda:coarse = one ellipsoid per link) or go2 (planar base); "
                   "required unless --plan records it")  # fmt: skip
    s.add_argument("--plan", default=None, help="PATH.json of 'splatplan plan': start at its first configuration and head for its last (go2: "
                   "tracking it as the route; panda: the end-effector pose there is the goal), with the robot, base pose and scene it records "
                   "unless flags give others")  # fmt: skip
    s.add_argument("--box", nargs=2, metavar=("LO", "HI"), default=None, help="go2: corners X,Y (or X,Y,YAW like plan's --box; the yaw is free) of "
                   "where the base may go: the goal must lie inside, the route and the obstacle memory stay inside (default: the scene's "
                   "bounds grown by the robot's footprint diameter)")  # fmt: skip
    s.add_argument("--scene", default=None, help="built-in scene name or a splat file (default tabletop for panda, apartment for go2); files without a .gt.json get a metric clearance")
    s.add_argument("--goal-pose", default=None, help="panda: X,Y,Z,QW,QX,QY,QZ end-effector goal (metres, wxyz world <- panda_hand_tcp)")
    s.add_argument("--goal", default=None, help="go2: X,Y goal of the base (metres); e.g. the final node of an RRT path")
    s.add_argument("--start", default=None, help="start configuration: 7 joint values (panda, default home) or X,Y,YAW (go2; default -2.3,-0.6,0 in the living room of apartment, the base study's start, else 0,0,0)")
    add_base_pose_arg(s)
    s.add_argument("--no-collision", action="store_true", help="switch the collision cost off (the baseline); every output says so")
    s.add_argument("--route", action="store_true", help="go2: plan a global RRT route on SE(2) first and track it (default: only when the straight line to the goal is blocked, facing the goal)")
    s.add_argument("--no-route", action="store_true", help="go2: never plan a route (the goal only, even when the straight line is blocked)")
    s.add_argument("--route-time", type=float_arg(gt=0, le=1e6), default=None, help="go2 --route: RRT time budget in seconds (default 60)")
    s.add_argument("--out", required=True, help="output folder (result.json, motion.png)")
    add_seed_arg(s, help="noise seed")
    add_device_arg(s)
    add_config_args(s, ArmConfig, prefix="arm_", skip=("mppi.seed",), group="panda (ArmConfig) options")
    add_config_args(s, BaseConfig, prefix="base_", skip=("mppi.seed",), group="go2 (BaseConfig) options")
    s.set_defaults(func=cmd_mpc)
    from ..eval.arm import ArmStudyConfig
    from ..eval.base import BaseStudyConfig

    for name, cls, help_ in (("arm", ArmStudyConfig, "Panda reaching behind a wall of tabletop, with/without the collision cost (paper Table IV, no image)"),
                             ("base", BaseStudyConfig, "Go2 driving to goals in other rooms of apartment given only the goal, with/without the collision cost")):  # fmt: skip
        e = eval_sub.add_parser(name, help=help_)
        e.add_argument("--out", required=True, help="output folder")
        e.add_argument("--quick", action="store_true", help="start from the small settings (< 2 min on 2 cores); flags still override them")
        add_config_args(e, cls, skip=("quick",), group=f"study options ({cls.__name__})")
        e.set_defaults(func=cmd_eval, study=name)
