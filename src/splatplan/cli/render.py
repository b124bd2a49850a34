"""`splatplan render`: one image (and optionally its depth) of a splat scene from one camera."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from ._flags import add_command, add_device_arg, check_device, float_arg, int_arg
from ._inputs import load_npy
from ._outputs import atomic_path
from ._values import parse_vec3

_IMAGE_EXT = (".png", ".jpg", ".jpeg")


def _load_matrix(path: str, shape: tuple[int, int], what: str, key: str) -> np.ndarray:
    """A (4, 4) / (3, 3) matrix from .npy or .json (a nested list, or an object with ``key``)."""
    p = Path(path)
    if p.suffix.lower() == ".npy":
        arr = load_npy(path, what)
    elif p.suffix.lower() == ".json":
        if not p.is_file():
            raise SplatplanError(f"{what} {path} does not exist")
        try:
            obj = json.loads(p.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise SplatplanError(f"{what} {path} is not valid JSON ({exc.__class__.__name__}: {exc})") from None
        if isinstance(obj, dict):
            if key not in obj:
                raise SplatplanError(f"{what} {path}: expected a {shape[0]}x{shape[1]} nested list or an object with a {key!r} field")
            obj = obj[key]
        try:
            arr = np.asarray(obj, dtype=np.float64)
        except (TypeError, ValueError):
            raise SplatplanError(f"{what} {path}: expected a {shape[0]}x{shape[1]} array of numbers") from None
    else:
        raise SplatplanError(f"{what} {path}: expected a .json or .npy file")
    if arr.shape == (1,) + shape:
        arr = arr[0]
    if arr.shape != shape:
        raise SplatplanError(f"{what} {path}: expected shape {shape}, got {arr.shape} (one camera per call)")
    return arr


def _scene(spec: str, filter_floaters: bool):
    from ..scenes.builtin import BUILTIN_SCENES, build_builtin

    if not Path(spec).exists() and spec in BUILTIN_SCENES:
        return build_builtin(spec)[0]
    from ._inputs import load_scene_file

    return load_scene_file(spec, filter_floaters=filter_floaters)


def cmd_render(args) -> int:
    from ..render import intrinsics_from_fov, look_at, render
    from ..render.config import check_image_size

    out = Path(args.out)
    if out.suffix.lower() not in _IMAGE_EXT:
        raise SplatplanError(f"--out {args.out}: expected a {', '.join(_IMAGE_EXT)} path")
    if args.depth and Path(args.depth).suffix.lower() not in (".png", ".npy"):
        raise SplatplanError(f"--depth {args.depth}: expected a .png (16-bit) or .npy (float32) path")
    if not (np.isfinite(args.depth_scale) and args.depth_scale > 0):
        raise SplatplanError(f"--depth-scale {args.depth_scale}: expected a finite number > 0")
    for p in [args.out] + ([args.depth] if args.depth else []):
        if not Path(p).parent.exists():
            raise SplatplanError(f"output folder {Path(p).parent} does not exist")
    # camera: viewmat file, or eye + look-at
    if args.viewmat:
        if args.eye or args.look_at:
            raise SplatplanError("give either --viewmat or --eye/--look-at, not both")
        viewmat = _load_matrix(args.viewmat, (4, 4), "--viewmat", "viewmat")
    else:
        if not (args.eye and args.look_at):
            raise SplatplanError("give the camera as --eye X,Y,Z --look-at X,Y,Z (and optionally --up), or --viewmat FILE")
        viewmat = look_at(parse_vec3(args.eye, "--eye"), parse_vec3(args.look_at, "--look-at"), parse_vec3(args.up, "--up"))
    w, h = check_image_size(args.width, args.height)
    if args.K:
        K = _load_matrix(args.K, (3, 3), "--K", "K")
    else:
        K = intrinsics_from_fov(args.fov, w, h)
    bg = parse_vec3(args.background, "--background")
    if np.any(bg < 0) or np.any(bg > 1):
        raise SplatplanError(f"--background {args.background!r}: each of R,G,B must lie in [0, 1]")
    device = check_device(args.device)
    scene = _scene(args.scene, not args.keep_floaters)
    t0 = time.perf_counter()
    res = render(scene, viewmat, K, w, h, near=args.near, far=args.far, background=bg, sh_degree=args.sh_degree,
                 device=device, backend=args.backend)  # fmt: skip
    dt = time.perf_counter() - t0
    from PIL import Image

    rgb = np.asarray(res.rgb)[0]
    img = Image.fromarray((np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8), mode="RGB")
    with atomic_path(out) as tmp:
        img.save(tmp, format="PNG" if out.suffix.lower() == ".png" else "JPEG")
    alpha = np.asarray(res.alpha)[0]
    print(f"rendered {w}x{h} of {args.scene} ({len(scene):,} splats, {args.backend} on {device}, {dt:.2f} s); "
          f"coverage (mean alpha) {float(alpha.mean()):.3f}: wrote {out}")  # fmt: skip
    if args.depth:
        depth = np.asarray(res.depth)[0].astype(np.float32)
        with atomic_path(args.depth) as tmp:
            if Path(args.depth).suffix.lower() == ".npy":
                with open(tmp, "wb") as f:
                    np.save(f, depth)
                note = "float32 view depth, scene units, 0 = nothing hit"
            else:
                d16 = np.clip(np.rint(depth * args.depth_scale), 0, 65535).astype(np.uint16)
                Image.fromarray(d16).save(tmp, format="PNG")
                note = f"16-bit, value = depth x {args.depth_scale:g} (clipped at 65535), 0 = nothing hit"
        hit = depth[alpha > 0]
        rng = f"{float(hit.min()):.4g}..{float(hit.max()):.4g}" if hit.size else "none"
        print(f"wrote {args.depth} ({note}; depth range {rng})")
    return 0


def register(sub, eval_sub) -> None:
    s = add_command(sub, "render", cmd_render, "render an image (and depth) of a splat scene",
                    "Render one pinhole view. Camera: --eye/--look-at/--up (+ --fov) or a 4x4 world-to-camera matrix (--viewmat, OpenCV "
                    "axes: x right, y down, z forward) with optional --K intrinsics. One call may take at most 2 GiB (outputs + workspace).")  # fmt: skip
    s.add_argument("scene", metavar="SCENE", help="splat file (any supported format) or a built-in scene name (stonehenge, tabletop, apartment)")
    s.add_argument("--eye", help="camera position X,Y,Z (scene frame)")
    s.add_argument("--look-at", dest="look_at", help="point the camera looks at X,Y,Z")
    s.add_argument("--up", default="0,0,1", help="world direction shown up in the image (default 0,0,1)")
    s.add_argument("--viewmat", help="FILE.json|.npy: 4x4 world-to-camera matrix (JSON: nested list or {'viewmat': ...})")
    s.add_argument("--K", help="FILE.json|.npy: 3x3 pixel intrinsics [[fx,0,cx],[0,fy,cy],[0,0,1]], pixel centres at +0.5 (default from --fov)")
    # --fov, --width, --height, --sh-degree: ranges checked by the renderer (its messages), finiteness here
    s.add_argument("--fov", type=float_arg(), default=60.0, help="horizontal field of view in degrees when --K is not given (default 60)")
    s.add_argument("--width", type=int_arg(), default=256, help="image width in pixels (default 256)")
    s.add_argument("--height", type=int_arg(), default=256, help="image height in pixels (default 256)")
    s.add_argument("--out", required=True, help="IMG.png or .jpg (8-bit RGB, background composited)")
    s.add_argument("--depth", help="DEPTH.png (16-bit, depth x --depth-scale) or DEPTH.npy (float32, scene units)")
    s.add_argument("--depth-scale", type=float_arg(ge=1e-6, le=1e6), default=1000.0, help="PNG depth units per scene unit (default 1000: mm for metric scenes)")
    s.add_argument("--background", default="0,0,0", help="background colour R,G,B in [0, 1] (default 0,0,0)")
    s.add_argument("--near", type=float_arg(ge=0, le=1e6), default=0.01, help="near plane: splats with view depth below it are culled (default 0.01)")
    s.add_argument("--far", type=float_arg(gt=0, allow_inf=True), default=1e10, help="far plane (default 1e10)")
    s.add_argument("--sh-degree", type=int_arg(), default=None, help="SH degree to evaluate 0..3 (default: all the scene has)")
    s.add_argument("--backend", default="auto", choices=["auto", "warp", "gsplat", "reference"], help="renderer (default auto = our Warp kernels)")
    s.add_argument("--keep-floaters", action="store_true", help="do not drop floaters when loading the scene")
    add_device_arg(s)
