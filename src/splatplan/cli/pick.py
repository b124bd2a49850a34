"""`splatplan pick`: points on a scene's surfaces, to name a goal without Python.

Prints a table (the top of the highest object, the horizontal surfaces, the largest and the nearest
walls with their normals, free floor for a ground robot, the nearest surface point to ``--near``) in
the scene's frame (z up, floor at z = 0 after ``scene align``; scene units, metres after align) and
writes it with ``--json``. The library side is :func:`splatplan.scenes.pick.pick_points`.

Exit codes: 0 done, 2 bad input.
"""

from __future__ import annotations

import numpy as np

from ..errors import SplatplanError
from ._common import _load, add_command, add_config_args, allow_negative_values, config_from_args, parse_vec3, robot_at, write_json

#: how far above the top the suggested gripper goal lies (scene units: metres after `scene align`)
ABOVE_TOP = 0.10


def _f(v) -> str:
    return ",".join(f"{x:.3f}" for x in np.asarray(v, dtype=np.float64).reshape(-1))


def _row(what: str, p, normal, size: str) -> str:
    p = np.asarray(p, dtype=np.float64)
    n = "" if normal is None else _f(normal)
    return f"{what:<9} {p[0]:>8.3f} {p[1]:>8.3f} {p[2]:>8.3f}  {n:<19} {size}"


def cmd_pick(args) -> int:
    from ..robots.footprint import robot_footprint
    from ..scenes.pick import PickConfig, pick_points

    if args.out is not None and not str(args.out).endswith(".json"):
        raise SplatplanError(f"--json {args.out}: expected a PATH.json")
    cfg = config_from_args(args, PickConfig).validate()
    near = None if args.near is None else parse_vec3(args.near, "--near")
    robot = None if args.robot is None else robot_at(args.robot, None)
    if robot is not None and robot.base == "fixed" and not robot.is_point:
        raise SplatplanError(f"--robot {args.robot}: a fixed-base arm has no footprint on the floor; pick's --robot is for ground robots (go2) and point robots")
    scene = _load(args.scene)
    res = pick_points(scene, cfg, footprint=None if robot is None else robot_footprint(robot), near=near)
    fl = res.floor
    print(f"pick {args.scene}: {res.n_splats:,} splats, {res.n_opaque:,} opaque (opacity >= {cfg.opacity_min:g}), grid cell {res.cell:.3g}; "
          "frame: the scene's (z up, floor at z = 0 after `scene align`), scene units (metres after align)")  # fmt: skip
    how = "given" if cfg.floor_z is not None else "fitted"
    if fl.found:
        print(f"floor: z = {fl.z:.3f} ({how}; splats at that height under {fl.coverage:.0%} of the footprint)")
    else:
        print(f"floor: none found (at z = {fl.z:.3f}, {how}, splats cover only {fl.coverage:.0%} of the footprint: an object capture?); no free floor")
    print(f"{'what':<9} {'x':>8} {'y':>8} {'z':>8}  {'normal':<19} size")
    for i, s in enumerate(res.surfaces):
        print(_row("top" if i == 0 else "surface", s.point, (0, 0, 1), f"area {s.area:.3g}" + (" (highest horizontal surface)" if i == 0 else "")))
    nearest = min(res.walls, key=lambda w: w.distance, default=None)
    for w in res.walls:
        tag = f", {w.distance:.3g} from {'--near' if near is not None else 'the centre'}" + (" (nearest)" if w is nearest else "")
        print(_row("wall", w.point, w.normal, f"{w.length:.3g} long, z {w.z[0]:.3g} to {w.z[1]:.3g}{tag}"))
    if res.free is not None:
        f = res.free
        who = f"{robot.name}: height {f.height:.3g}, footprint radius {f.radius:.3g}" if robot is not None else f"height {f.height:.3g}, a point; --robot go2 for its footprint"
        if not f.regions:
            print(f"free      no floor cell is free for {who}")
        for p, area, clear in f.regions:
            print(_row("free", p, None, f"region area {area:.3g}, clearance {clear:.3g} ({who})"))
    if res.near is not None:
        print(_row("near", res.near.point, res.near.normal, f"{res.near.distance:.3g} from --near {_f(res.near.query)}"))
    if res.top is not None:
        t = res.top.point
        print(f"use: a gripper pointing down {ABOVE_TOP:g} above the top: --goal-pose {_f(t[:2])},{t[2] + ABOVE_TOP:.3f},0,1,0,0")
    if res.free is not None and res.free.regions and (robot is None or robot.walks_on_terrain):
        p = res.free.regions[0][0]
        print(f"use: a ground robot's goal in the largest free region: plan --goal {_f(p[:2])},0 (X,Y,YAW) or mpc --goal {_f(p[:2])}")
    if args.out is not None:
        write_json(args.out, {"scene": str(args.scene), "robot": None if robot is None else robot.name, **res.to_json()})
        print(f"wrote {args.out}")
    return 0


def register(sub, eval_sub) -> None:
    from ..robots.builtin import ROBOT_NAME_HELP
    from ..scenes.pick import PickConfig

    s = add_command(sub, "pick", cmd_pick, "points on a scene's surfaces to name a goal: the top of the highest object, walls, free floor, the nearest point",
                    "Points on the surfaces of a scene, from its opaque splat means, in its frame (z up, floor at z = 0 after `scene align`; "
                    "scene units, metres after align): the top of the highest object and the other horizontal surfaces, the largest walls "
                    "and the nearest one with their normals, free floor cells for a ground robot (--robot go2: its height and footprint), "
                    "and the nearest surface point to --near. Prints a table; --json writes it.")  # fmt: skip
    allow_negative_values(s)
    s.add_argument("scene", metavar="SCENE")
    s.add_argument("--near", default=None, metavar="X,Y,Z", help="report the surface point nearest to this point (walls face it and are measured from it)")
    s.add_argument("--robot", default=None, help=f"free floor for this ground or point robot (its height and footprint radius); {ROBOT_NAME_HELP}")
    s.add_argument("--json", dest="out", default=None, metavar="PATH.json", help="write the points as JSON (atomically)")
    add_config_args(s, PickConfig, group="pick options (PickConfig; lengths in scene units)")
