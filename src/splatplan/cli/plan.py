"""`splatplan plan`: RRT (+ refinement) between two points."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from ._common import (  # noqa: F401
    ROBOT_HELP, _load, _out_dir, add_config_args, add_device_arg, atomic_path, config_from_args, load_poses, parse_robot, parse_vec3, write_json,
)


def cmd_plan(args) -> int:
    from ..metric import CollisionChecker
    from ..planners import plan

    start, goal = parse_vec3(args.start, "--start"), parse_vec3(args.goal, "--goal")
    axes = parse_robot(args.robot)
    if not np.allclose(axes, axes[0]):
        raise SplatplanError("splatplan plan takes a sphere robot ('sphere:R'); use the Python API for ellipsoid links")
    if not str(args.out).endswith(".json"):
        raise SplatplanError(f"--out {args.out}: expected a .json path")
    scene = _load(args.scene)
    checker = CollisionChecker(scene, n_sigma=args.n_sigma, device=args.device)
    res = plan(checker, start, goal, radius=float(axes[0]), refine=args.refine, seed=args.seed)
    out = {
        "success": bool(res.success),
        "path": np.asarray(res.path).tolist(),
        "length": float(res.length) if np.isfinite(res.length) else None,  # null when no path
        "time_s": float(res.time_s),
        "n_nodes": int(res.n_nodes),
    }
    write_json(args.out, out)
    msg = f"path found: length {res.length:.4f}" if res.success else f"no path found ({res.message})"
    print(f"{msg}; {res.n_nodes} nodes, {res.time_s:.3f} s -> {args.out}")
    return 0


def register(sub, eval_sub) -> None:
    s = sub.add_parser("plan", help="RRT (+ refinement) from start to goal for a sphere robot")
    s.add_argument("scene", metavar="SCENE")
    s.add_argument("--start", required=True, help="X,Y,Z (scene frame)")
    s.add_argument("--goal", required=True, help="X,Y,Z (scene frame)")
    s.add_argument("--robot", default="sphere:0.015", help="sphere:R (default sphere:0.015)")
    s.add_argument("--n-sigma", type=float, default=1.0)
    s.add_argument("--refine", action="store_true", help="zeroth-order refinement of the RRT path")
    s.add_argument("--seed", type=int, default=0)
    add_device_arg(s)
    s.add_argument("--out", required=True, help="PATH.json")
    s.set_defaults(func=cmd_plan)
