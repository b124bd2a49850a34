"""`splatplan info` and `splatplan scene`: summarise a splat file, write a built-in scene."""

from __future__ import annotations

import json
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import SplatplanError
from ._common import _Unset, _load, add_command, dumps_json, add_seed_arg, add_config_args, atomic_dir, config_from_args, float_arg, int_arg, move_into, parse_vec3


def cmd_info(args) -> int:
    from ..scenes.filters import filter_floaters
    from ..scenes.sanity import absurd_splats

    s = _load(args.scene, filter_floaters=False, usable=False)
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
    from ..scenes.align import AlignConfig, default_up_hint, describe_frame
    from ..scenes.conventions import align_sidecar_path, read_align_sidecar

    frame = describe_frame(s, AlignConfig(up_hint=args.up_hint or default_up_hint(args.scene)))
    info.update(frame)
    side = read_align_sidecar(args.scene)
    if side is not None:  # written by `scene align`: its record, not a new guess, says where up is
        info["aligned"] = {"sidecar": str(align_sidecar_path(args.scene)), "frame": side.get("frame"), "floor_z": side.get("floor_z"),
                           "date": side.get("date"), "wall": side.get("wall"), "matches_file": side.get("n_out") == len(s)}  # fmt: skip
    if args.json:
        print(dumps_json(info))
        return 0
    print(f"{info['path']}: {info['count']:,} splats ({info['format']}{', 2DGS disks' if s.is_2d else ''})")
    print(f"  bounds of means (file frame, scene units): min {np.round(lo, 4).tolist()}  max {np.round(hi, 4).tolist()}")
    print(f"  largest std per splat: median {info['max_std_median']:.4g}, p99 {info['max_std_p99']:.4g}; median opacity {info['opacity_median']:.3f}")
    print(f"  SH rest coefficients: {info['sh_rest_coeffs']}; floaters by the default rule (o < 0.1 and max std > 5x median): {info['floaters_default_rule']}")
    for line in info["absurd"]:
        print(f"  warning: absurd splats: {line}")
    rl, rh = np.round(frame["robust_bounds_min"], 4).tolist(), np.round(frame["robust_bounds_max"], 4).tolist()
    pl, ph = frame["robust_percentiles"]
    print(f"  robust bounds ({pl:g}-{ph:g} percentile of the means): min {rl}  max {rh}")
    sh = frame["shell"]
    if sh["count"]:
        print(f"  shell/outliers: {sh['count']:,} splats outside the robust box, at median radius {sh['radius_median']:.3g} (max {sh['radius_max']:.3g}) from its centre")
    else:
        print("  shell/outliers: none outside the robust box")
    g = frame["up_guess"]
    al = info.get("aligned")
    if al is not None and not al["matches_file"]:
        print(f"  warning: {al['sidecar']} records an alignment of a different file (splat count differs); guessing instead")
    if al is not None and al["matches_file"]:
        print(f"  aligned by `splatplan scene align`{' on ' + al['date'] if al.get('date') else ''}: {al['frame']} (recorded in {al['sidecar']})")
    elif g is None:
        print(f"  up axis: no guess ({frame['up_note']})")
    else:
        print(f"  up axis guess: {g['up_axis']} (normal {g['up']}, confidence {g['confidence']:.2f}); floor at {g['floor_height']:.4g} along it "
              f"(`splatplan scene align` moves it to z = 0)")  # fmt: skip
    print(f"  scale: {frame['scale_note']}")
    for w in frame["warnings"]:
        print(f"  warning: {w}")
    return 0


def cmd_align(args) -> int:
    """`splatplan scene align IN --out OUT`: write the aligned scene and its transform sidecar."""
    from ..scenes.align import AlignConfig, align_scene, default_up_hint, nearest_axis
    from ..scenes.load import save_scene

    if args.input is None:
        raise SplatplanError("scene align needs an input: splatplan scene align IN --out OUT")
    out = Path(args.out)
    if out.is_dir():
        raise SplatplanError(f"--out {args.out} is a directory; give a PATH.ply")
    if out.suffix.lower() != ".ply":
        raise SplatplanError(f"--out {args.out}: expected a .ply path (an INRIA ply)")
    if not out.parent.exists():
        raise SplatplanError(f"output folder {out.parent} does not exist")
    if Path(args.input).resolve() == out.resolve():
        raise SplatplanError("--out must differ from the input (the input is never overwritten)")
    cfg = config_from_args(args, AlignConfig, prefix="align_")
    if getattr(args, "cfg_align_up_hint", None) in (None, _Unset):
        cfg = replace(cfg, up_hint=default_up_hint(args.input))
    if args.up is not None:
        cfg = replace(cfg, up=args.up)
    if args.floor is not None:
        cfg = replace(cfg, floor=args.floor)
    if args.scale is not None:
        cfg = replace(cfg, scale=args.scale)
    if args.rotate_z is not None:
        cfg = replace(cfg, rotate_z=args.rotate_z)
    if args.translate is not None:
        cfg = replace(cfg, translate=tuple(parse_vec3(args.translate, "--translate", max_abs=1e9)))
    if args.crop is not None:
        lo, hi = (parse_vec3(c, "--crop", max_abs=1e9) for c in args.crop)
        cfg = replace(cfg, crop=tuple(lo) + tuple(hi))
    if args.drop_floaters:
        cfg = replace(cfg, drop_floaters=True)
    if args.keep_shell:
        cfg = replace(cfg, keep_shell=True)
    if args.wall is not None:
        cfg = replace(cfg, wall=args.wall)
    png = None if args.png is None else Path(args.png)
    if png is not None and (png.suffix.lower() != ".png" or png.is_dir() or not png.parent.exists()):
        raise SplatplanError(f"--png {args.png}: expected a PATH.png in an existing folder")
    cfg.validate()
    scene = _load(args.input, filter_floaters=False)
    aligned, res = align_scene(scene, cfg)
    doc = {"input": str(args.input), "output": str(out), "written_by": f"splatplan {__version__} scene align",
           "date": datetime.now(timezone.utc).isoformat(timespec="seconds"), "floor_z": res.floor_z(), **res.to_json()}  # fmt: skip
    side = sidecar_path(out)
    fig = None
    if png is not None:
        from ..scenes.align_plot import alignment_figure

        up_txt = "given" if res.up is None else f"{res.up.to_json()['up_axis']} of the input ({res.up.method})"
        fig = alignment_figure(aligned, f"{out.name}: {res.frame_text()}; up = {up_txt}", res.floor_z(), None if cfg.wall == "none" else cfg.wall)
    with atomic_dir(out.parent) as tmp:  # the files appear together or not at all
        save_scene(aligned, tmp / out.name)
        (tmp / side.name).write_text(dumps_json(doc, indent=2) + "\n")
        if fig is not None and png is not None:
            fig.savefig(tmp / "view.png", dpi=80)
            move_into(tmp / "view.png", png)
        move_into(tmp / side.name, side)
        move_into(tmp / out.name, out)
    g = res.up
    if g is not None and res.wall is not None:
        print(f"wall: normal {np.round(res.wall['normal_in'], 4).tolist()} of the input -> {res.wall['axis']}, the wall at 0 along it; "
              f"up {nearest_axis(g.up)} (normal {np.round(g.up, 4).tolist()}, {res.wall['up_source']})")  # fmt: skip
    elif g is not None and g.method == "given":
        print(f"up: {cfg.up} (given); floor at {g.floor_height:.4g} along it -> z = {res.floor_z() if res.floor_z() is not None else 0:g}")
    elif g is not None:
        why = "; only the capture convention (--align-up-hint) separated it from the runner-up" if g.hint_decides else ""
        print(f"up: {g.to_json()['up_axis']} (normal {np.round(g.up, 4).tolist()}, support plane under {'n/a' if g.plane is None else format(g.plane.coverage, '.0%')} of the scene, "
              f"margin {g.margin:.2f}, confidence {g.confidence:.2f}{why}); floor at {g.floor_height:.4g} along it -> z = {res.floor_z():g}")  # fmt: skip
    if res.n_shell_dropped:
        print(f"dropped a background shell of {res.n_shell_dropped:,} splats far beyond the scene (--keep-shell keeps it)")
    dropped = [f"the shell {res.n_shell_dropped:,}"] if res.n_shell_dropped else []
    dropped += [f"--crop dropped {res.n_cropped:,}"] if res.n_cropped else []
    dropped += [f"--drop-floaters dropped {res.n_floaters:,}"] if res.n_floaters else []
    crop = f"; {' and '.join(dropped)} of {res.n_in:,} splats (the rest in order)" if dropped else "; every splat kept, in order"
    print(f"transform (x_out = T [x_in; 1], scale {res.scale:g}):")
    for row in res.transform:
        print("  [" + ", ".join(f"{v: .6f}" for v in row) + "]")
    print(f"wrote {out} ({res.n_out:,} splats{crop}) and {side}" + (f"; the views in {png}" if png is not None else ""))
    return 0


def sidecar_path(out: Path) -> Path:
    """The transform sidecar of an aligned scene: PATH.ply -> PATH.align.json."""
    from ..scenes.conventions import align_sidecar_path

    return align_sidecar_path(out)


def cmd_scene(args) -> int:
    from ..scenes.builtin import BUILTIN_SCENES, write_builtin
    from ..scenes.builtin.stonehenge import ground_truth_path

    scene_cmd = args.name  # the scene subcommand: a built-in's name, from-moveit or align
    if getattr(args, "haze", False) and scene_cmd in ("from-moveit", "align"):
        raise SplatplanError(f"--haze is an option of the built-in apartment ('splatplan scene apartment --haze --out X.ply'), not of scene {scene_cmd}")
    if args.name == "from-moveit":
        return _scene_from_moveit(args)
    if args.name == "align":
        return cmd_align(args)
    for flag in ("n_splats", "spacing"):
        if getattr(args, flag) is not None:
            raise SplatplanError(f"--{flag.replace('_', '-')} goes with 'splatplan scene from-moveit SCENE.yaml --out X.ply'")
    if args.input is not None:
        raise SplatplanError(f"scene {args.name}: unexpected argument {args.input!r} (only 'scene align IN' and 'scene from-moveit SCENE.yaml' take an input)")
    given = [f for f in ("up", "floor", "scale", "rotate_z", "translate", "crop", "wall", "png") if getattr(args, f) is not None]
    given += [f for f in ("drop_floaters", "keep_shell") if getattr(args, f)]
    if given:
        raise SplatplanError(f"--{given[0].replace('_', '-')} is an option of 'scene align IN --out OUT', not of a built-in scene")
    if args.name not in BUILTIN_SCENES:
        raise SplatplanError(f"unknown built-in scene {args.name!r}: available: {', '.join(BUILTIN_SCENES)}, or from-moveit SCENE.yaml")
    if not 1 <= args.level <= 5:
        raise SplatplanError(f"--level must be 1..5, got {args.level}")
    if not 0 <= args.seed < 2**63:
        raise SplatplanError(f"--seed must be an integer >= 0, got {args.seed}")
    out = _check_out_ply(args.out)
    # Both files are written into a temp folder beside the output and moved into place only when
    # both are complete (an interrupted run leaves nothing behind).
    with atomic_dir(out.parent) as tmp:
        ply, gt = write_builtin(args.name, tmp / out.name, seed=args.seed, level=args.level, haze=args.haze)
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
    from .._resources import require_bytes
    from ..scenes.builtin import SPLAT_BUILD_BYTES
    from ..scenes.builtin.surface_splats import n_splats_for_spacing
    from ..scenes.builtin.stonehenge import ground_truth_path
    from ..scenes.moveit import DEFAULT_N_SPLATS, load_moveit_scene, write_moveit

    if args.input is None:
        raise SplatplanError("scene from-moveit needs the planning-scene YAML: splatplan scene from-moveit SCENE.yaml --out X.ply")
    if args.n_splats is not None and args.spacing is not None:
        raise SplatplanError("give --n-splats or --spacing, not both")
    if not 0 <= args.seed < 2**63:
        raise SplatplanError(f"--seed must be an integer >= 0, got {args.seed}")
    out = _check_out_ply(args.out)
    scene = load_moveit_scene(args.input)  # reject bad input before any work
    if args.spacing is not None:
        n = n_splats_for_spacing(scene, float(args.spacing), seed=args.seed)
        what, lower = f"--spacing {args.spacing:g} m: {n:,} splats for this scene's surface", "the splat count (a larger --spacing)"
    else:
        n = DEFAULT_N_SPLATS if args.n_splats is None else int(args.n_splats)
        what, lower = f"{n:,} splats", "the splat count (--n-splats)"
    if n < 1000:
        raise SplatplanError(f"--n-splats must be >= 1000, got {n}" if args.spacing is None else
                             f"--spacing {args.spacing:g} m gives only {n} splats for this scene (at least 1000): give a smaller spacing")  # fmt: skip
    require_bytes(float(n) * SPLAT_BUILD_BYTES, what, lower)
    with atomic_dir(out.parent) as tmp:
        ply, gt = write_moveit(scene, tmp / out.name, n_splats=n, seed=args.seed)
        gt_dest = ground_truth_path(out)
        move_into(gt, gt_dest)
        move_into(ply, out)
    print(f"wrote {out} ({n:,} splats) and its exact ground truth {gt_dest}")
    return 0


def register(sub, eval_sub) -> None:
    s = add_command(sub, "info", cmd_info, "summarise a splat file")
    s.add_argument("scene", metavar="SCENE", help="splat file (.ply INRIA/2DGS/compressed, .splat, .spz, gsplat .pt)")
    s.add_argument("--json", action="store_true", help="print one JSON object")
    s.add_argument("--up-hint", default=None, choices=("+x", "-x", "+y", "-y", "+z", "-z"),
                   help="capture convention that breaks ties between perpendicular bounding planes in the up guess "
                   "(default +z for files splatplan wrote, with a .align.json/.gt.json beside them, and nerfstudio plys, else -y)")  # fmt: skip
    from ..scenes.align import AlignConfig
    from ..scenes.conventions import FORMAT_FRAMES

    s = add_command(sub, "scene", cmd_scene, "write a built-in scene or splats of a MoveIt planning scene with its ground truth, or align a capture",
                    "`scene NAME --out PATH.ply` writes a built-in scene; `scene from-moveit SCENE.yaml --out PATH.ply` samples "
                    "a MoveIt planning scene into splats (ground truth in PATH.gt.json); `scene align IN --out OUT.ply` puts a capture in the "
                    "robot's world (z up, floor at z = 0; the transform goes to OUT.align.json and is printed). With --up auto it refuses "
                    "rather than guess when no plane supports the scene or two could be the floor. Frames after loading: "
                    + "; ".join(f"{k}: {v}" for k, v in FORMAT_FRAMES.items()) + ".")  # fmt: skip
    s.add_argument("name", metavar="NAME", help="built-in scene name: stonehenge | tabletop | apartment; or 'from-moveit' or 'align'")
    s.add_argument("input", metavar="IN", nargs="?", default=None, help="align: the input splat file; from-moveit: a MoveIt planning-scene "
                   "YAML (box, cylinder, sphere primitives)")  # fmt: skip
    s.add_argument("--out", required=True, help="PATH.ply (built-in / from-moveit: ground truth goes to PATH.gt.json; align: the transform to PATH.align.json)")
    g = s.add_argument_group("align options")
    g.add_argument("--up", default=None, help="align: the input's up axis: auto (the plane under the scene, default; refuses when unsure) | +x | -x | +y | -y | +z | -z")
    g.add_argument("--floor", default=None, help="align: auto (fitted, default) | none | Z (floor height along the up axis, input units) -> z = 0")
    g.add_argument("--scale", type=float_arg(ge=1e-6, le=1e6), default=None, help="align: uniform scale after the rotation (default 1)")
    g.add_argument("--rotate-z", type=float_arg(ge=-3600, le=3600), default=None, help="align: rotation about the new z axis, degrees (default 0)")
    g.add_argument("--translate", default=None, metavar="X,Y,Z", help="align: translation added last (output units)")
    g.add_argument("--crop", nargs=2, default=None, metavar=("LO", "HI"), help="align: keep splats in the box LO=X,Y,Z .. HI=X,Y,Z (aligned frame); says how many were dropped")
    g.add_argument("--drop-floaters", action="store_true", help="align: drop faint isolated splats (floaters in free space: opacity < 0.3, "
                   "mean 8-NN distance > 3x the median); says how many")  # fmt: skip
    g.add_argument("--wall", default=None, choices=("+x", "-x", "+y", "-y"), help="align a wall fixture (a tap, a switch): the largest wall-like plane's normal "
                   "(out of the wall) goes to this axis and the wall to 0 along it; up from --up, else the capture convention")  # fmt: skip
    g.add_argument("--keep-shell", action="store_true", help="align: keep a detected background shell (far splats beyond an empty gap; dropped and counted by default)")
    g.add_argument("--png", default=None, metavar="FILE.png", help="align: draw the aligned scene (front, side, top views coloured by height, the floor, "
                   "the up axis) to check that up is up")  # fmt: skip
    add_config_args(s, AlignConfig, prefix="align_", skip=("up", "floor", "scale", "rotate_z", "translate", "crop", "drop_floaters", "keep_shell", "wall"),
                    group="align fit options (AlignConfig)")  # fmt: skip
    s.add_argument("--haze", action="store_true", help="apartment only: add the real-capture look of phone captures of apartments "
                   "(faint haze above the floor, a mirror layer under a shiny kitchen floor, floor-level matter)")
    s.add_argument("--level", type=int_arg(ge=1, le=5), default=1, help="Gaussian-size level 1..5 (larger, fewer splats)")
    add_seed_arg(s, help="layout and sampling seed, an integer >= 0 (default 0)")
    s.add_argument("--n-splats", type=int_arg(ge=1), default=None, help="from-moveit only: total splats (default 100000: ~7-8 mm spacing on a metre-scale workcell)")
    s.add_argument("--spacing", type=float_arg(ge=1e-9, le=1e3), default=None, metavar="M", help="from-moveit only: sample at this surface spacing (m) "
                   "instead, a count per area (3.5e-3 is eval mbm's default: ~500k splats on an MBM workcell)")  # fmt: skip
