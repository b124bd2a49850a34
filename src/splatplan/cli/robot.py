"""`splatplan robot info|fit`: inspect a robot, fit collision ellipsoids to a URDF's link meshes.

* ``splatplan robot info NAME|URDF [--json] [--model tight|coarse|cover (default tight)] [--finger-opening M]
  [--meshes-from REF.urdf] [--no-measure]``: links, ellipsoids, joint limits, motion bounds, and
  per link the model's fit measured against the collision meshes (``robots.fit_measure``: count,
  coverage of surface / interior samples, union volume ratio with its Monte Carlo standard error,
  farthest reach beyond the mesh). ``--meshes-from`` measures against another URDF's meshes
  (e.g. VAMP's ``panda_spherized.urdf`` against ``panda.urdf``).
* ``splatplan robot fit URDF|NAME --out ELLIPSOIDS.yaml [--method split|opt|cover] [--per-link K]
  [--from-visual]``: fits enclosing ellipsoids (``split``, default: every mesh vertex and box
  corner inside, see ``robots.fit``), the tight and safe union (``opt``, ``robots.fit_opt``) or the
  greedy union (``cover``, ``robots.fit_cover``), writes the
  YAML (load it with ``load_robot(URDF, ellipsoids=YAML)`` or name it ``<urdf stem>.ellipsoids.yaml``
  beside the URDF) and a PNG of the ellipsoids over the geometry next to it (``--no-png`` skips it).

Links without collision geometry are skipped with a note on stderr (``--from-visual`` fits them
to their visual meshes instead).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from ..robots.builtin import BUILTIN_STATE, DEFAULT_MODEL, PANDA_MODELS, ROBOT_NAME_HELP
from ..robots.fit import MAX_PER_LINK
from ._flags import add_command, float_arg, int_arg
from ._outputs import dumps_json

#: ``--per-link``: ellipsoids (slabs) per link, 1..MAX_PER_LINK
PER_LINK = int_arg(ge=1, le=MAX_PER_LINK)


def _robot_args(p) -> None:
    p.add_argument("--ellipsoids", default=None, help="YAML with the collision ellipsoids (default: built-in / sidecar / fitted)")
    p.add_argument("--per-link", type=PER_LINK, default=1, help="ellipsoids per link when fitting (k >= 1; slabs along the principal axis)")
    p.add_argument("--from-visual", action="store_true", help="fit links without collision geometry to their visual meshes")
    p.add_argument("--model", default=None, choices=tuple(PANDA_MODELS), help=f"built-in panda only: collision model (default {DEFAULT_MODEL}; coarse = one ellipsoid per link; same as NAME panda:MODEL)")
    p.add_argument("--finger-opening", type=float_arg(ge=0, le=0.04), default=None, help="built-in panda only: each finger's distance from the centre line (m, 0..0.04)")


def _note_skipped(skipped: list[str]) -> None:
    if skipped:
        print(f"splatplan: note: {len(skipped)} link(s) without collision geometry skipped: {', '.join(skipped)}"
              " (use --from-visual to fit them to their visual meshes)", file=sys.stderr)  # fmt: skip


def cmd_info(args) -> int:
    from ..robots import load_robot

    if args.per_link < 1:
        raise SplatplanError(f"--per-link must be >= 1, got {args.per_link}")
    extra = {k: v for k, v in (("model", args.model), ("finger_opening", args.finger_opening)) if v is not None}
    robot = load_robot(args.robot, ellipsoids=args.ellipsoids, per_link=args.per_link, from_visual=args.from_visual, **extra) if (
        args.ellipsoids or args.per_link != 1 or args.from_visual) else load_robot(args.robot, **extra)  # fmt: skip
    d = robot.describe()
    measure = None
    if args.meshes_from and not Path(args.meshes_from).is_file():
        raise SplatplanError(f"--meshes-from {args.meshes_from}: no such URDF")
    if not args.no_measure and (args.meshes_from or robot.info.get("urdf")):
        from ..robots.fit_measure import measure_robot

        measure = measure_robot(robot, args.meshes_from or None, n_samples=args.samples)
        d["model_fit"] = {"reference": str(args.meshes_from or robot.info.get("urdf")), "samples": args.samples,
                          "links": {k: (v.to_dict() if v is not None else None) for k, v in measure.items()}}  # fmt: skip
    if args.json:
        print(dumps_json(d))
        return 0
    print(f"{robot.name}: {robot.dof} dof, {len(robot.link_names)} links, {robot.n_ellipsoids} ellipsoids, "
          f"{len(robot.self_collision_pairs)} self-collision pairs, smallest semi-axis {robot.min_semi_axis:.4g} m")  # fmt: skip
    bp = robot.base_pose
    print(f"  base pose (world <- base): translation {np.round(bp[:3, 3], 4).tolist()}"
          + ("" if np.allclose(bp[:3, :3], np.eye(3)) else f", rotation {np.round(bp[:3, :3], 4).tolist()}"))  # fmt: skip
    print("  joints (limits, velocity, motion bound = max ellipsoid-point speed per unit joint speed):")
    for j in d["joints"]:
        print(f"    {j['name']:<22} [{j['lower']:9.4g}, {j['upper']:9.4g}]  vel {j['velocity']:7.4g}  default {j['default']:8.4g}  bound {j['motion_bound_m']:.4g} m")
    print("  ellipsoids per link (semi-axes in m; volume ratio = ellipsoids / collision geometry):")
    per: dict[str, list] = {}
    for e in d["ellipsoids"]:
        per.setdefault(e["link"], []).append(e["semi_axes"])
    for link, axes in per.items():
        rep = d["fit"].get(link, {})
        ratio = rep.get("volume_ratio")
        rtxt = f"ratio {ratio:.2f}" if isinstance(ratio, (int, float)) else "ratio n/a"
        ax = "; ".join(",".join(f"{v:.3f}" for v in a) for a in axes)
        print(f"    {link:<22} {len(axes)}x  {rtxt:<11} ({rep.get('source', '?')}: {'+'.join(rep.get('geometry', []))})  [{ax}]")
    if measure is not None:
        print(f"  model fit against {d['model_fit']['reference']} (Monte Carlo, {args.samples} samples per link; "
              "coverage = fraction of mesh surface / interior samples inside the model; reach = farthest model point outside the mesh):")  # fmt: skip
        print(f"    {'link':<22} {'n':>3}  {'cov surf':>8}  {'cov int':>8}  {'volume ratio':>14}  {'reach m':>8}")
        for link, m in measure.items():
            if m is None:
                print(f"    {link:<22}   (no mesh or box in the reference)")
                continue
            print(f"    {link:<22} {m.n:>3}  {m.coverage_surface:8.4f}  {m.coverage_interior:8.4f}  {m.volume_ratio:7.3f} +- {m.volume_ratio_se:.3f}  {m.reach_m:8.4f}")
    if d["links_without_geometry"]:
        print(f"  links without collision geometry (no ellipsoid): {', '.join(d['links_without_geometry'])}")
    return 0


def cmd_fit(args) -> int:
    from ..robots.builtin import build_robot, builtin_urdf
    from ..robots.fit import fit_model, save_yaml
    from ..robots.plot import plot_robot_ellipsoids
    from ..robots.urdf import read_urdf

    if args.per_link < 1:
        raise SplatplanError(f"--per-link must be >= 1, got {args.per_link}")
    out = Path(args.out)
    if out.suffix.lower() not in (".yaml", ".yml"):
        raise SplatplanError(f"--out {args.out}: expected a .yaml path")
    if out.is_dir():
        raise SplatplanError(f"--out {args.out} is a directory; give a PATH.yaml")
    if not out.parent.exists():
        raise SplatplanError(f"output folder {out.parent} does not exist")
    src = args.urdf
    srdf = None
    if src in BUILTIN_STATE:
        urdf, srdf = builtin_urdf(src)
    else:
        urdf = Path(src)
        if not urdf.is_file():
            raise SplatplanError(f"URDF {src} does not exist (or use a built-in: panda, go2)")
    model = read_urdf(urdf)
    from ..robots.fit_cover import FitConfig
    from ._config_flags import config_from_args

    from ..robots.fit_opt import OptConfig

    method = "split" if args.per_link > 1 else args.method
    cfg = {"cover": lambda: config_from_args(args, FitConfig, prefix="fit_").validate(),
           "opt": lambda: config_from_args(args, OptConfig, prefix="opt_").validate()}.get(method, lambda: None)()  # fmt: skip
    ells = fit_model(model, per_link=args.per_link, from_visual=args.from_visual, method=method, config=cfg)
    _note_skipped(ells.skipped)
    save_yaml(ells, out, robot=model.name, urdf=str(src),
              note=f"generated by: splatplan robot fit {src} --out {out.name} --method {method} --per-link {args.per_link}"
                   + (" --from-visual" if args.from_visual else "") + " (link frame, metres, wxyz)")  # fmt: skip
    print(f"wrote {out}: {ells.n} ellipsoids on {len(ells.report)} links")
    for link, rep in ells.report.items():
        print(f"  {link:<22} {rep['n']}x  volume ratio {rep['volume_ratio']:.2f}  ({rep['source']}: {'+'.join(rep['geometry'])})")
    if not args.no_png:
        from ._outputs import atomic_path

        sr = srdf if srdf is not None else (urdf.with_suffix(".srdf") if urdf.with_suffix(".srdf").is_file() else None)
        state = BUILTIN_STATE.get(src)
        robot = build_robot(model, sr, None, None, "fixed", None, out, 1, False, state=state, name=model.name)
        fig = plot_robot_ellipsoids(robot, model, q=robot.q_default, from_visual=args.from_visual)
        png = out.with_suffix(".png")
        with atomic_path(png) as tmp:
            fig.savefig(tmp, format="png")
        print(f"wrote {png}")
    return 0


def register(sub, eval_sub) -> None:
    p = sub.add_parser("robot", help="robots: info (links, ellipsoids, limits), fit (ellipsoids to link meshes)")
    rs = p.add_subparsers(dest="robot_cmd", required=True, metavar="ACTION")
    pi = add_command(rs, "info", cmd_info, "links, ellipsoids, joint limits, volume ratios of a robot")
    pi.add_argument("robot", metavar="NAME|URDF", help=ROBOT_NAME_HELP)
    pi.add_argument("--json", action="store_true", help="print one JSON object")
    pi.add_argument("--meshes-from", default=None, metavar="URDF", help="measure the model against this URDF's collision meshes (same link names)")
    pi.add_argument("--no-measure", action="store_true", help="skip measuring the model against the meshes")
    pi.add_argument("--samples", type=int_arg(ge=100, le=2_000_000), default=5000, help="Monte Carlo samples per link for the model measurement (standard error ~ 1/sqrt(samples))")
    _robot_args(pi)
    pf = add_command(rs, "fit", cmd_fit, "fit enclosing ellipsoids to a URDF's link meshes -> YAML (+ PNG)")
    pf.add_argument("urdf", metavar="URDF", help="a .urdf path (or a built-in: panda, go2)")
    pf.add_argument("--out", required=True, help="output ELLIPSOIDS.yaml (a PNG of the fit is written next to it)")
    pf.add_argument("--method", choices=("split", "opt", "cover"), default="split", help="split (default): enclosing ellipsoids, K per link; opt: a few "
                    "optimised ellipsoids per link, certified to contain the meshes (tight and safe; ~1 CPU-minute per link); cover: "
                    "the older greedy union (looser, more ellipsoids)")  # fmt: skip
    pf.add_argument("--per-link", type=PER_LINK, default=1, help="split: ellipsoids per link (k >= 1; slabs along the principal axis)")
    pf.add_argument("--from-visual", action="store_true", help="fit links without collision geometry to their visual meshes")
    pf.add_argument("--no-png", action="store_true", help="skip the PNG")
    from ..robots.fit_cover import FitConfig
    from ._config_flags import add_config_args

    add_config_args(pf, FitConfig, prefix="fit_", group="cover fitter (--method cover)")
    from ..robots.fit_opt import OptConfig

    add_config_args(pf, OptConfig, prefix="opt_", group="optimising fitter (--method opt)")
