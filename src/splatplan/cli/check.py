"""`splatplan check`: the CollisionSplatting metric for a batch of robot poses."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from ._common import (  # noqa: F401
    ROBOT_HELP, _load, _out_dir, add_config_args, add_device_arg, atomic_path, config_from_args, load_poses, parse_robot, parse_vec3, write_json,
)


def cmd_check(args) -> int:
    from ..metric import CollisionChecker

    axes = parse_robot(args.robot)
    centers, quats = load_poses(args.poses)
    if args.out and not str(args.out).endswith(".npz"):
        raise SplatplanError(f"--out {args.out}: expected a .npz path")
    scene = _load(args.scene)
    checker = CollisionChecker(scene, n_sigma=args.n_sigma, device=args.device)
    res = checker.query(centers, quats, axes)
    n_hit = int(res.in_collision.sum())
    print(f"{len(centers):,} poses checked against {len(scene):,} splats (n_sigma={args.n_sigma}, device={checker.device}): "
          f"{n_hit:,} in collision, min s2~ = {float(np.min(res.min_s2)) if len(centers) else float('nan'):.4g}")  # fmt: skip
    if args.out:
        with atomic_path(args.out) as tmp:
            with open(tmp, "wb") as f:
                np.savez(f, **res.as_dict())
        print(f"wrote {args.out}")
    return 0


def register(sub, eval_sub) -> None:
    s = sub.add_parser("check", help="CollisionSplatting metric for a batch of robot poses")
    s.add_argument("scene", metavar="SCENE")
    s.add_argument("--poses", required=True, help="POSES.npy: (B,3) centres or (B,7) centre + wxyz quaternion, scene frame")
    s.add_argument("--robot", required=True, help=ROBOT_HELP)
    s.add_argument("--n-sigma", type=float, default=1.0, help="conservatism n_sigma >= 0 (default 1)")
    s.add_argument("--out", help="OUT.npz with min_s2, n_colliding, in_collision, softmin, cost, each (B,)")
    add_device_arg(s)
    s.set_defaults(func=cmd_check)
