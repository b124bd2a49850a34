"""Command-line interface. Thin: parse, call the library, print, exit codes.

Exit codes: 0 success, 2 bad input or impossible request (one-line message, no traceback),
1 unexpected internal error, 130 interrupted. Output files are written atomically.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .errors import SplatplanError

ROBOT_HELP = "robot link: 'sphere:R' or 'ellipsoid:A,B,C' (semi-axes, scene units)"


# ---------------------------------------------------------------------------- helpers
def parse_robot(spec: str) -> np.ndarray:
    """'sphere:R' or 'ellipsoid:A,B,C' -> semi-axes (3,) float64."""
    kind, _, rest = spec.partition(":")
    try:
        vals = [float(v) for v in rest.split(",")] if rest else []
    except ValueError:
        raise SplatplanError(f"--robot {spec!r}: numbers expected after ':' ({ROBOT_HELP})") from None
    if kind == "sphere" and len(vals) == 1:
        axes = np.full(3, vals[0])
    elif kind == "ellipsoid" and len(vals) == 3:
        axes = np.asarray(vals)
    else:
        raise SplatplanError(f"--robot {spec!r} not understood: {ROBOT_HELP}")
    if not np.all(np.isfinite(axes)) or np.any(axes <= 0):
        raise SplatplanError(f"--robot {spec!r}: sizes must be finite and > 0")
    return axes


def parse_vec3(text: str, what: str) -> np.ndarray:
    try:
        v = np.asarray([float(x) for x in text.split(",")], dtype=np.float64)
    except ValueError:
        raise SplatplanError(f"{what} {text!r}: expected three comma-separated numbers X,Y,Z") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise SplatplanError(f"{what} {text!r}: expected three finite comma-separated numbers X,Y,Z")
    return v


def load_poses(path: str) -> tuple[np.ndarray, np.ndarray | None]:
    """POSES.npy of shape (B, 3) centres or (B, 7) centre + wxyz quaternion."""
    p = Path(path)
    if not p.is_file():
        raise SplatplanError(f"poses file {path} does not exist")
    try:
        arr = np.load(p, allow_pickle=False)
    except Exception as exc:  # numpy raises several types for broken files
        raise SplatplanError(f"poses file {path} is not a readable .npy array ({exc.__class__.__name__}: {exc})") from None
    if not np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.complexfloating):
        raise SplatplanError(f"poses file {path}: expected a real numeric array, got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] not in (3, 7):
        raise SplatplanError(f"poses file {path}: expected shape (B, 3) centres or (B, 7) centre + wxyz quaternion, got {arr.shape}")
    arr = arr.astype(np.float64)
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise SplatplanError(f"poses file {path}: {int(bad.sum())} row(s) contain NaN or Inf (first: row {int(np.argmax(bad))})")
    if arr.shape[1] == 7:
        q = arr[:, 3:]
        if np.any(np.linalg.norm(q, axis=1) < 1e-8):
            raise SplatplanError(f"poses file {path}: zero quaternion in row {int(np.argmax(np.linalg.norm(q, axis=1) < 1e-8))}")
        return arr[:, :3], q
    return arr, None


@contextmanager
def atomic_path(path: str | Path):
    """Yield a temp path in the destination folder; move it over ``path`` only on success."""
    dest = Path(path)
    if dest.parent and not dest.parent.exists():
        raise SplatplanError(f"output folder {dest.parent} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=dest.suffix, dir=dest.parent or ".")
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, dest)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_json(path: str | Path, obj) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=2) + "\n")


def _out_dir(path: str) -> Path:
    d = Path(path)
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SplatplanError(f"cannot create output folder {d}: {exc.strerror}") from None
    return d


def _load(path: str, filter_floaters: bool = True):
    from .scenes.load import load_scene

    return load_scene(path, filter_floaters=filter_floaters)


# ---------------------------------------------------------------------------- commands
def cmd_info(args) -> int:
    from .scenes.filters import filter_floaters

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
    }
    if args.json:
        print(json.dumps(info))
        return 0
    print(f"{info['path']}: {info['count']:,} splats ({info['format']}{', 2DGS disks' if s.is_2d else ''})")
    print(f"  bounds of means (file frame, scene units): min {np.round(lo, 4).tolist()}  max {np.round(hi, 4).tolist()}")
    print(f"  largest std per splat: median {info['max_std_median']:.4g}, p99 {info['max_std_p99']:.4g}; median opacity {info['opacity_median']:.3f}")
    print(f"  SH rest coefficients: {info['sh_rest_coeffs']}; floaters by the default rule (o < 0.1 and max std > 5x median): {info['floaters_default_rule']}")
    return 0


def cmd_check(args) -> int:
    from .metric import CollisionChecker

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


def cmd_scene(args) -> int:
    from .scenes.stonehenge import write_stonehenge

    if args.name != "stonehenge":
        raise SplatplanError(f"unknown built-in scene {args.name!r}: available: stonehenge")
    if not 1 <= args.level <= 5:
        raise SplatplanError(f"--level must be 1..5, got {args.level}")
    if not str(args.out).endswith(".ply"):
        raise SplatplanError(f"--out {args.out}: expected a .ply path")
    if not Path(args.out).parent.exists():
        raise SplatplanError(f"output folder {Path(args.out).parent} does not exist")
    ply, gt = write_stonehenge(args.out, level=args.level, seed=args.seed)
    print(f"wrote {ply} and its ground truth {gt}")
    return 0


def cmd_demo(args) -> int:
    from .demo import run_demo

    run_demo(_out_dir(args.out), device=args.device)
    return 0


def cmd_plan(args) -> int:
    from .metric import CollisionChecker
    from .planners import plan

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


def cmd_eval(args) -> int:
    out = _out_dir(args.out)
    if args.study == "pr":
        from .eval.pr import run_pr

        run_pr(out, scene=args.scene, gt=args.gt, quick=args.quick)
    elif args.study == "throughput":
        from .eval.throughput import run_throughput

        run_throughput(out, quick=args.quick, device=args.device)
    elif args.study == "conservatism":
        from .eval.conservatism import run_conservatism

        run_conservatism(out, quick=args.quick, seed=args.seed)
    elif args.study == "linearization":
        from .eval.linearization import run_linearization

        run_linearization(out, quick=args.quick, seed=args.seed)
    return 0


# ---------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="splatplan", description="Collision-aware motion planning in Gaussian-splat scenes.")
    sub = p.add_subparsers(dest="cmd", required=True, metavar="COMMAND")

    s = sub.add_parser("info", help="summarise a splat file")
    s.add_argument("scene", metavar="SCENE", help="splat file (.ply INRIA/2DGS/compressed, .splat, .spz, gsplat .pt)")
    s.add_argument("--json", action="store_true", help="print one JSON object")
    s.set_defaults(func=cmd_info)

    s = sub.add_parser("check", help="CollisionSplatting metric for a batch of robot poses")
    s.add_argument("scene", metavar="SCENE")
    s.add_argument("--poses", required=True, help="POSES.npy: (B,3) centres or (B,7) centre + wxyz quaternion, scene frame")
    s.add_argument("--robot", required=True, help=ROBOT_HELP)
    s.add_argument("--n-sigma", type=float, default=1.0, help="conservatism n_sigma >= 0 (default 1)")
    s.add_argument("--out", help="OUT.npz with min_s2, n_colliding, in_collision, softmin, cost, each (B,)")
    s.add_argument("--device", default="cpu", help="cpu | cuda | cuda:N (default cpu)")
    s.set_defaults(func=cmd_check)

    s = sub.add_parser("scene", help="write a built-in scene with its ground truth")
    s.add_argument("name", metavar="NAME", help="built-in scene name: stonehenge")
    s.add_argument("--out", required=True, help="PATH.ply (ground truth goes to PATH.gt.json)")
    s.add_argument("--level", type=int, default=1, help="Gaussian-size level 1..5 (larger, fewer splats)")
    s.add_argument("--seed", type=int, default=0)
    s.set_defaults(func=cmd_scene)

    s = sub.add_parser("demo", help="the main job on the built-in scene: collision field and plans")
    s.add_argument("--out", default="demo_out", help="output folder (default demo_out)")
    s.add_argument("--device", default="cpu")
    s.set_defaults(func=cmd_demo)

    s = sub.add_parser("plan", help="RRT (+ refinement) from start to goal for a sphere robot")
    s.add_argument("scene", metavar="SCENE")
    s.add_argument("--start", required=True, help="X,Y,Z (scene frame)")
    s.add_argument("--goal", required=True, help="X,Y,Z (scene frame)")
    s.add_argument("--robot", default="sphere:0.015", help="sphere:R (default sphere:0.015)")
    s.add_argument("--n-sigma", type=float, default=1.0)
    s.add_argument("--refine", action="store_true", help="zeroth-order refinement of the RRT path")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--device", default="cpu")
    s.add_argument("--out", required=True, help="PATH.json")
    s.set_defaults(func=cmd_plan)

    s = sub.add_parser("eval", help="the paper's studies: pr, throughput, conservatism, linearization")
    s.add_argument("study", choices=["pr", "throughput", "conservatism", "linearization"])
    s.add_argument("--out", required=True, help="output folder")
    s.add_argument("--quick", action="store_true", help="small version for smoke tests (< 1 min)")
    s.add_argument("--scene", default="stonehenge", help="(pr) 'stonehenge' or a splat file with --gt")
    s.add_argument("--gt", help="(pr) ground-truth .gt.json for a scene file")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--device", default="cpu")
    s.set_defaults(func=cmd_eval)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except SplatplanError as exc:
        print(f"splatplan: error: {exc}", file=sys.stderr)
        return 2
    except FileNotFoundError as exc:
        print(f"splatplan: error: {exc.filename or exc}: no such file", file=sys.stderr)
        return 2
    except PermissionError as exc:
        print(f"splatplan: error: permission denied: {exc.filename or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("splatplan: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        print("splatplan: error: out of memory; try a smaller batch or --device cuda", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
