"""Rendering throughput on the built-in 200k-splat Stonehenge, batched cameras around it.

images/s = camera batch / wall time of one ``SplatRenderer.render`` call (median of --repeats
timed calls after a warm-up call on the same batch). Cameras: a ring of B views at radius 0.9
(the scene spans about 1 unit), heights 0.2..0.5, looking at the centre, 60 degree horizontal
field of view. The scene is used as built (200k splats incl. its 0.05% floaters, SH degree 0).

On a shared machine the wall time depends on what else runs; the table therefore also gives
the process CPU time per image and the throughput that CPU time implies on all cores of this
machine with nothing else running ("CPU-bound images/s" = cores x 1000 / CPU ms per image), and
the load average during the run. On CUDA, gsplat is timed beside our kernels when it imports,
with the PSNR between the two.

    python benchmarks/render.py [--device cpu|cuda] [--batch 32] [--sizes 64,224] [--repeats 3]
        [--out benchmarks/results/render.json] [--example docs/render_example.png]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

TARGETS = {64: 20.0, 224: 4.0}  # images/s on the 2-core CPU (issue #9)


def ring_cameras(b: int, seed: int = 0):
    from splatplan.render import look_at

    rng = np.random.default_rng(seed)
    ang = np.linspace(0.0, 2.0 * np.pi, b, endpoint=False) + rng.uniform(0, 0.1)
    eyes = np.stack([0.9 * np.cos(ang), 0.9 * np.sin(ang), rng.uniform(0.2, 0.5, b)], axis=1)  # (B, 3) world, z up
    return look_at(eyes, np.array([0.0, 0.0, 0.03]))


def _time(fn, repeats: int, sync=lambda: None):
    fn()
    sync()
    walls, cpus = [], []
    for _ in range(repeats):
        c0, t0 = time.process_time(), time.perf_counter()
        out = fn()
        sync()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return float(np.median(walls)), float(np.median(cpus)), out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--sizes", default="64,224")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--n-splats", type=int, default=None, help="scene size (default: Stonehenge level 1, 200k)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "render.json"))
    ap.add_argument("--example", default=str(Path(__file__).parents[1] / "docs" / "render_example.png"), help="PNG of one view ('' to skip)")
    args = ap.parse_args(argv)

    from splatplan._warp import cpu_threads, resolve_device
    from splatplan.render import SplatRenderer, intrinsics_from_fov
    from splatplan.scenes.builtin.stonehenge import build_stonehenge

    device = resolve_device(args.device)
    scene, _ = build_stonehenge(level=1, seed=0, n_splats=args.n_splats)
    viewmats = ring_cameras(args.batch)
    cores = cpu_threads()
    sync = lambda: None  # noqa: E731
    gs = None
    if device.startswith("cuda"):
        from splatplan._warp import wp

        sync = lambda: wp().synchronize_device(device)  # noqa: E731
        from splatplan.render.gsplat_backend import GsplatRenderer, gsplat_available

        if gsplat_available():
            gs = GsplatRenderer(scene, device)
    rows = []
    with SplatRenderer(scene, device) as r:
        for size in [int(s) for s in args.sizes.split(",")]:
            k = intrinsics_from_fov(60.0, size, size)
            load0 = os.getloadavg()[0]
            wall, cpu, res = _time(lambda: r.render(viewmats, k, size, size), args.repeats, sync)
            row = {
                "backend": "warp", "device": device, "size": size, "batch": args.batch,
                "images_per_s": args.batch / wall, "wall_s": wall, "cpu_ms_per_image": 1000.0 * cpu / args.batch,
                "cpu_bound_images_per_s": cores * args.batch / cpu if cpu > 0 else None,
                "load_avg_1min": (load0 + os.getloadavg()[0]) / 2, "mean_alpha": float(np.mean(res.alpha)),
                "target_images_per_s": TARGETS.get(size) if device == "cpu" else None,
            }  # fmt: skip
            rows.append(row)
            if gs is not None:
                gwall, _, gres = _time(lambda: gs.render(viewmats, k, size, size), args.repeats, sync)
                mse = float(np.mean((np.asarray(gres.rgb) - np.asarray(res.rgb)) ** 2))
                rows.append({"backend": "gsplat", "device": device, "size": size, "batch": args.batch,
                             "images_per_s": args.batch / gwall, "wall_s": gwall,
                             "psnr_vs_warp_db": 10 * np.log10(1.0 / max(mse, 1e-20))})  # fmt: skip
        if args.example:
            from PIL import Image

            k = intrinsics_from_fov(60.0, 320, 200)
            ex = r.render(ring_cameras(1, seed=3), k, 320, 200, background=(0.55, 0.7, 0.9))
            Path(args.example).parent.mkdir(parents=True, exist_ok=True)
            Image.fromarray((np.clip(np.asarray(ex.rgb)[0], 0, 1) * 255 + 0.5).astype(np.uint8)).save(args.example, optimize=True)

    print(f"\nStonehenge, {len(scene):,} splats, device {device}, {cores} CPU core(s), batch {args.batch}\n")
    print("| backend | size | images/s (wall) | CPU ms / image | CPU-bound images/s | load avg | target |")
    print("|---|---|---|---|---|---|---|")
    for x in rows:
        cb = x.get("cpu_bound_images_per_s")
        extra = f" (PSNR vs warp {x['psnr_vs_warp_db']:.1f} dB)" if "psnr_vs_warp_db" in x else ""
        print(f"| {x['backend']}{extra} | {x['size']}x{x['size']} | {x['images_per_s']:.1f} | "
              f"{x.get('cpu_ms_per_image', float('nan')):.1f} | {'' if cb is None else f'{cb:.1f}'} | "
              f"{x.get('load_avg_1min', float('nan')):.1f} | {x.get('target_images_per_s') or ''} |")  # fmt: skip
    out = {
        "scene": {"name": "stonehenge", "level": 1, "n_splats": len(scene)},
        "machine": {"platform": platform.platform(), "python": sys.version.split()[0], "cores": cores},
        "cameras": "ring at radius 0.9, z 0.2..0.5, looking at (0, 0, 0.03), 60 deg horizontal fov",
        "rows": rows,
    }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")
    print(f"\nwrote {args.out}" + (f" and {args.example}" if args.example else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
