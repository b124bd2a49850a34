"""`splatplan view`: a browser viewer (viser) of a scene, a robot, plans, trees and MPC runs."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from ..robots.builtin import ROBOT_NAME_HELP
from ._results import RecordedFrame, check_scene, fill_robot, finite_rows, load_result, read_frame, read_plan
from ._common import _load, add_base_pose_arg, add_command, add_config_args, add_terrain_args, config_from_args, ground_robot_scene, parse_base_pose, robot_at


def _read_mpc(folder: str) -> tuple[np.ndarray, RecordedFrame | None]:
    p = Path(folder) / "result.json"
    if not p.is_file():
        raise SplatplanError(f"--mpc {folder}: no result.json there (the output folder of 'splatplan mpc')")
    obj = load_result(p, "--mpc")
    arr = finite_rows(obj, "trajectory", f"--mpc {p}", "a \"trajectory\" list of states", "(T, dof) list of finite numbers")
    return arr, read_frame(obj, f"--mpc {folder}")


def _read_tree(path: str):
    p = Path(path)
    if not p.is_file():
        raise SplatplanError(f"--tree {path}: no such file")
    try:
        with np.load(p, allow_pickle=False) as z:
            nodes, parents = np.asarray(z["nodes"], dtype=np.float64), np.asarray(z["parents"], dtype=np.int64)
    except Exception as exc:  # numpy raises several types for broken files
        raise SplatplanError(f"--tree {path}: expected an .npz with arrays 'nodes' (N, D) and 'parents' (N,) ({exc.__class__.__name__})") from None
    if nodes.ndim != 2 or parents.shape != (len(nodes),):
        raise SplatplanError(f"--tree {path}: 'nodes' (N, D) and 'parents' (N,) expected, got {nodes.shape} and {parents.shape}")
    if not np.all(np.isfinite(nodes)):
        raise SplatplanError(f"--tree {path}: 'nodes' contains NaN or Inf")
    bad = (parents < -1) | (parents >= len(nodes))
    if bad.any():
        i = int(np.argmax(bad))
        raise SplatplanError(f"--tree {path}: parents[{i}] = {int(parents[i])} is not a node index (-1 for a root, else 0..{len(nodes) - 1})")
    return nodes, parents


def cmd_view(args) -> int:
    from ..viewer import SplatViewer, ViewerConfig

    try:
        import viser  # noqa: F401
    except ImportError:
        raise SplatplanError("the viewer needs the optional extra: pip install 'splatplan[viewer]'") from None
    cfg = config_from_args(args, ViewerConfig)
    plan, plan_frame = read_plan(args.plan) if args.plan else (None, None)
    traj, mpc_frame = _read_mpc(args.mpc) if args.mpc else (None, None)
    tree = _read_tree(args.tree) if args.tree else None
    frame = plan_frame or mpc_frame  # where the result was made: its robot and base pose unless given
    fill_robot(args, frame)
    check_scene(args.scene, frame)
    robot = None
    if args.robot:
        robot = robot_at(args.robot, parse_base_pose(args.base_pose))
    elif args.base_pose is not None:
        raise SplatplanError("--base-pose places the robot given with --robot")
    scene = _load(args.scene)
    collision_scene = None
    if robot is not None and robot.walks_on_terrain:  # a ground robot: the floor's splats are terrain, not obstacles
        collision_scene = ground_robot_scene(scene, args, cfg.n_sigma)
    viewer = SplatViewer(scene, robot=robot, plan=plan, trajectory=traj, tree=tree, config=cfg, collision_scene=collision_scene)
    viewer.start()
    print(f"splatplan viewer: {viewer.url}  ({len(scene):,} splats, robot {viewer.robot.name}; Ctrl-C to stop)", flush=True)
    try:
        while True:
            time.sleep(0.25)
    except KeyboardInterrupt:
        print("stopping the viewer", flush=True)
        return 130  # interrupted, as every command (the CLI's exit codes)
    finally:
        viewer.stop()


def register(sub, eval_sub) -> None:
    from ..viewer.app import ViewerConfig  # numpy only: viser is imported when the server starts

    s = add_command(sub, "view", cmd_view, "open a browser viewer of a scene, robot, plan, tree or MPC run")
    s.add_argument("scene", metavar="SCENE", help="splat file or a built-in scene file")
    s.add_argument("--robot", help=f"robot: {ROBOT_NAME_HELP} (default: the robot --plan / --mpc records, else a sphere sized to the scene)")
    add_base_pose_arg(s, help="X,Y,Z[,QW,QX,QY,QZ]: where the robot's base stands (metres, wxyz); default the base pose --plan / --mpc records, else the origin")
    s.add_argument("--plan", help="PATH.json written by 'splatplan plan'")
    s.add_argument("--mpc", help="output folder of 'splatplan mpc' (its result.json trajectory is animated)")
    s.add_argument("--tree", help="TREE.npz with 'nodes' (N, D) and 'parents' (N,)")
    add_config_args(s, ViewerConfig, group="viewer options")
    add_terrain_args(s)
