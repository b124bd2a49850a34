"""`splatplan demo`: the main job on the built-in scene."""

from __future__ import annotations

from ..errors import SplatplanError
from ._flags import add_command, add_device_arg, add_seed_arg
from ._outputs import out_dir


def cmd_demo(args) -> int:
    from ..demo import run_demo

    if args.seed < 0:
        raise SplatplanError(f"--seed must be an integer >= 0, got {args.seed}")
    run_demo(out_dir(args.out), device=args.device, seed=args.seed)
    return 0


def register(sub, eval_sub) -> None:
    s = add_command(sub, "demo", cmd_demo, "the main job on the built-in scene: collision field and plans")
    s.add_argument("--out", default="demo_out", help="output folder (default demo_out)")
    add_seed_arg(s, help="scene and planner seed, an integer >= 0 (default 0)")
    add_device_arg(s)
