"""`splatplan eval STUDY`: the paper's studies (one nested subcommand per study)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from ._common import (  # noqa: F401
    ROBOT_HELP, _load, _out_dir, add_config_args, add_device_arg, atomic_path, config_from_args, load_poses, parse_robot, parse_vec3, write_json,
)


def cmd_eval(args) -> int:
    out = _out_dir(args.out)
    if args.study == "pr":
        from ..eval.pr import run_pr

        run_pr(out, scene=args.scene, gt=args.gt, quick=args.quick)
    elif args.study == "throughput":
        from ..eval.throughput import run_throughput

        run_throughput(out, quick=args.quick, device=args.device)
    elif args.study == "conservatism":
        from ..eval.conservatism import run_conservatism

        run_conservatism(out, quick=args.quick, seed=args.seed)
    elif args.study == "linearization":
        from ..eval.linearization import run_linearization

        run_linearization(out, quick=args.quick, seed=args.seed)
    return 0


STUDIES = {
    "pr": "E1 precision-recall against the four baselines (paper Fig. 3)",
    "throughput": "E2 checks/s and memory of every method (paper Table I)",
    "conservatism": "E3 path length / clearance vs n_sigma (paper Table II, Fig. 4)",
    "linearization": "E4 scenes M1..M5 of growing splat size (paper Table III, Fig. 5)",
}


def register(sub, eval_sub) -> None:
    for name, help_ in STUDIES.items():
        s = eval_sub.add_parser(name, help=help_)
        s.add_argument("--out", required=True, help="output folder")
        s.add_argument("--quick", action="store_true", help="small version for smoke tests (< 1 min)")
        if name == "pr":
            s.add_argument("--scene", default="stonehenge", help="'stonehenge' or a splat file with --gt")
            s.add_argument("--gt", help="ground-truth .gt.json for a scene file")
        else:
            s.set_defaults(scene="stonehenge", gt=None)
        s.add_argument("--seed", type=int, default=0)
        add_device_arg(s)
        s.set_defaults(func=cmd_eval, study=name)
