"""`splatplan info` and `splatplan scene`: summarise a splat file, write a built-in scene."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from ._common import SEED, _load, atomic_dir, int_arg, move_into


def cmd_info(args) -> int:
    from ..scenes.filters import filter_floaters
    from ..scenes.sanity import absurd_splats

    s = _load(args.scene, filter_floaters=False)
    lo, hi = s.bounds()
    smax = s.scales.max(1)
    _, rep = filter_floaters(s)
    info = {
        "path": str(args.scene),
        "format": s.source_format,
        "count": len(s),
        "bounds_min": lo.tolist(),
        "bounds_max": hi.tolist(),
        "is_2dgs": s.is_2d,
        "sh_rest_coeffs": 0 if s.sh_rest is None else int(s.sh_rest.shape[1]),
        "max_std_median": float(np.median(smax)),
        "max_std_p99": float(np.quantile(smax, 0.99)),
        "opacity_median": float(np.median(s.opacities)),
        "floaters_default_rule": int(rep.n_dropped),
        "absurd": absurd_splats(s),  # values a corrupt file or a wrong unit gives (scenes.sanity)
    }
    if args.json:
        print(json.dumps(info))
        return 0
    print(f"{info['path']}: {info['count']:,} splats ({info['format']}{', 2DGS disks' if s.is_2d else ''})")
    print(f"  bounds of means (file frame, scene units): min {np.round(lo, 4).tolist()}  max {np.round(hi, 4).tolist()}")
    print(f"  largest std per splat: median {info['max_std_median']:.4g}, p99 {info['max_std_p99']:.4g}; median opacity {info['opacity_median']:.3f}")
    print(f"  SH rest coefficients: {info['sh_rest_coeffs']}; floaters by the default rule (o < 0.1 and max std > 5x median): {info['floaters_default_rule']}")
    for line in info["absurd"]:
        print(f"  warning: absurd splats: {line}")
    return 0


def cmd_scene(args) -> int:
    from ..scenes.builtin import BUILTIN_SCENES, write_builtin
    from ..scenes.stonehenge import ground_truth_path

    if args.name == "from-moveit":
        return _scene_from_moveit(args)
    if args.source is not None or args.n_splats is not None:
        raise SplatplanError("a SCENE.yaml and --n-splats go with 'splatplan scene from-moveit SCENE.yaml --out X.ply'")
    if args.name not in BUILTIN_SCENES:
        raise SplatplanError(f"unknown built-in scene {args.name!r}: available: {', '.join(BUILTIN_SCENES)}, or from-moveit SCENE.yaml")
    if not 1 <= args.level <= 5:
        raise SplatplanError(f"--level must be 1..5, got {args.level}")
    if not 0 <= args.seed < 2**63:
        raise SplatplanError(f"--seed must be an integer >= 0, got {args.seed}")
    out = Path(args.out)
    if out.suffix.lower() != ".ply":
        raise SplatplanError(f"--out {args.out}: expected a .ply path")
    if out.is_dir():
        raise SplatplanError(f"--out {args.out} is a directory; give a PATH.ply")
    if not out.parent.exists():
        raise SplatplanError(f"output folder {out.parent} does not exist")
    # Both files are written into a temp folder beside the output and moved into place only when
    # both are complete (an interrupted run leaves nothing behind).
    with atomic_dir(out.parent) as tmp:
        ply, gt = write_builtin(args.name, tmp / out.name, seed=args.seed, level=args.level)
        gt_dest = ground_truth_path(out)
        move_into(gt, gt_dest)
        move_into(ply, out)
    print(f"wrote {out} and its ground truth {gt_dest}")
    return 0


def _check_out_ply(text: str) -> Path:
    out = Path(text)
    if out.suffix.lower() != ".ply":
        raise SplatplanError(f"--out {text}: expected a .ply path")
    if out.is_dir():
        raise SplatplanError(f"--out {text} is a directory; give a PATH.ply")
    if not out.parent.exists():
        raise SplatplanError(f"output folder {out.parent} does not exist")
    return out


def _scene_from_moveit(args) -> int:
    """``splatplan scene from-moveit SCENE.yaml --out X.ply``: splats + exact ground truth X.gt.json."""
    from ..scenes.moveit import DEFAULT_N_SPLATS, load_moveit_scene, write_moveit
    from ..scenes.stonehenge import ground_truth_path

    if args.source is None:
        raise SplatplanError("scene from-moveit needs the planning-scene YAML: splatplan scene from-moveit SCENE.yaml --out X.ply")
    n = DEFAULT_N_SPLATS if args.n_splats is None else int(args.n_splats)
    if n < 1000:
        raise SplatplanError(f"--n-splats must be >= 1000, got {n}")
    if not 0 <= args.seed < 2**63:
        raise SplatplanError(f"--seed must be an integer >= 0, got {args.seed}")
    out = _check_out_ply(args.out)
    load_moveit_scene(args.source)  # reject bad input before any work
    with atomic_dir(out.parent) as tmp:
        ply, gt = write_moveit(args.source, tmp / out.name, n_splats=n, seed=args.seed)
        gt_dest = ground_truth_path(out)
        move_into(gt, gt_dest)
        move_into(ply, out)
    print(f"wrote {out} ({n:,} splats) and its exact ground truth {gt_dest}")
    return 0


def register(sub, eval_sub) -> None:
    s = sub.add_parser("info", help="summarise a splat file")
    s.add_argument("scene", metavar="SCENE", help="splat file (.ply INRIA/2DGS/compressed, .splat, .spz, gsplat .pt)")
    s.add_argument("--json", action="store_true", help="print one JSON object")
    s.set_defaults(func=cmd_info)
    s = sub.add_parser("scene", help="write a built-in scene, or splats of a MoveIt planning scene, with its ground truth")
    s.add_argument("name", metavar="NAME", help="built-in scene name: stonehenge | tabletop | apartment; or from-moveit (then SCENE.yaml)")
    s.add_argument("source", nargs="?", metavar="SCENE.yaml", help="with from-moveit: a MoveIt planning-scene YAML (box, cylinder, sphere primitives)")
    s.add_argument("--out", required=True, help="PATH.ply (ground truth goes to PATH.gt.json)")
    s.add_argument("--level", type=int_arg(ge=1, le=5), default=1, help="Gaussian-size level 1..5 (larger, fewer splats)")
    s.add_argument("--seed", type=SEED, default=0, help="layout and sampling seed, an integer >= 0 (default 0)")
    s.add_argument("--n-splats", type=int_arg(ge=1), default=None, help="from-moveit only: total splats (default 100000: ~7-8 mm spacing on a metre-scale workcell)")
    s.set_defaults(func=cmd_scene)
