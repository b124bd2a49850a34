"""Image-encoder throughput: images/s for the thumbnail, a tiny random DINOv2, ViT-S/14 with random
weights, and EfficientNet-Lite0 (ImageNet weights) on batches of RGB images.

Inputs are (B, H, W, 3) float32 numpy images in [0, 1] (default 32 x 224 x 224), so the timing
includes the numpy -> torch conversion, resizing/normalisation and the forward pass, as a planner
would call ``encode``. Random DINOv2 weights cost the same as real ones (same architecture).
One warm-up batch, then the median of ``--repeats`` timed batches, in wall-clock time and in process
CPU time (all threads; on a shared, loaded machine the wall clock also counts waiting for a core). torch's intra-op thread count is
set to ``--threads`` for the run and restored afterwards.

    python benchmarks/encoders.py [--device cpu|cuda] [--batch 32] [--size 224] [--threads 2]
                                  [--encoders thumbnail,dinov2-tiny,dinov2-vits14,efficientnet-lite0]
                                  [--out benchmarks/results/encoders.json]

Prints a markdown table and writes JSON (and the table as .md beside it).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

DEFAULT = "thumbnail,dinov2-tiny,dinov2-vits14,efficientnet-lite0"
RANDOM = {"dinov2-tiny", "dinov2-vits14", "dinov2-vitb14", "dinov2-vitl14"}  # no weights here: random, same cost


def _images(b: int, size: int, seed: int = 0) -> np.ndarray:
    """(b, size, size, 3) float32 smooth random colour fields in [0, 1]."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:size, 0:size] / size
    k = rng.normal(size=(b, 3, 2)) * 6
    ph = rng.uniform(0, 6.3, size=(b, 3))
    img = 0.5 + 0.4 * np.sin(k[..., 0, None, None] * xx + k[..., 1, None, None] * yy + ph[..., None, None])  # (b, 3, H, W)
    return np.ascontiguousarray(np.moveaxis(img, 1, -1), dtype=np.float32)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--size", type=int, default=224, help="input image side and the encoders' input size (thumbnail: 16)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2, help="torch intra-op threads during the run (restored afterwards)")
    ap.add_argument("--encoders", default=DEFAULT)
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "encoders.json"))
    args = ap.parse_args(argv)

    import torch

    from splatplan.encoders import load_encoder

    names = [n.strip() for n in args.encoders.split(",") if n.strip()]
    x = _images(args.batch, args.size)
    threads_before = torch.get_num_threads()
    torch.set_num_threads(args.threads)
    rows = []
    try:
        for name in names:
            kw = {} if name == "thumbnail" else {"image_size": args.size}
            enc = load_encoder(name, device=args.device, random_init=name in RANDOM, batch_size=args.batch, **kw)
            sync = torch.cuda.synchronize if enc.device.type == "cuda" else (lambda: None)
            enc.encode(x)  # warm-up
            sync()
            times, cpu = [], []
            for _ in range(args.repeats):
                t0, c0 = time.perf_counter(), time.process_time()
                enc.encode(x)
                sync()
                times.append(time.perf_counter() - t0)
                cpu.append(time.process_time() - c0)
            med, cmed = float(np.median(times)), float(np.median(cpu))
            n_params = sum(p.numel() for p in enc.model.parameters()) if getattr(enc, "model", None) is not None else 0
            rows.append({
                "encoder": enc.name, "requested": name, "dim": enc.dim,
                "weights": "random (same architecture and cost)" if name in RANDOM else ("none (weight-free)" if name == "thumbnail" else "pretrained ImageNet"),
                "params": int(n_params), "input": f"{args.size}x{args.size}", "encoder_input": f"{enc.image_size[0]}x{enc.image_size[1]}",
                "batch": args.batch, "s_per_batch": med, "images_per_s": args.batch / med, "times_s": times,
                "cpu_s_per_batch": cmed, "images_per_cpu_s": args.batch / cmed,
            })
            enc.close()
    finally:
        torch.set_num_threads(threads_before)

    head = ("| encoder | weights | params | dim | encoder input | batch | s / batch | images/s | process CPU s / batch | images / CPU s |\n"
            "|---|---|---:|---:|---|---:|---:|---:|---:|---:|")
    lines = [f"| {r['encoder']} | {r['weights']} | {r['params'] / 1e6:.2f}M | {r['dim']} | {r['encoder_input']} | {r['batch']} | {r['s_per_batch']:.3f} | "
             f"{r['images_per_s']:.1f} | {r['cpu_s_per_batch']:.3f} | {r['images_per_cpu_s']:.1f} |" for r in rows]
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    note = (f"device {args.device}, torch {torch.__version__}, {args.threads} torch threads, inputs {args.batch} x {args.size} x {args.size} x 3 "
            f"float32 numpy; median of {args.repeats} after a warm-up; 1-min load average at the end {load[0]:.2f} (shared machine: "
            f"wall-clock images/s fall when other processes compete for the cores; process CPU time, all threads, does much less)")
    table = "\n".join([head, *lines]) + f"\n\n{note}\n"
    print(table)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    res = {"device": args.device, "torch": torch.__version__, "torch_threads": args.threads, "batch": args.batch, "size": args.size,
           "repeats": args.repeats, "platform": platform.platform(), "cpu_count": os.cpu_count(), "loadavg_1min_end": load[0], "rows": rows}
    out.write_text(json.dumps(res, indent=2) + "\n")
    out.with_suffix(".md").write_text(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
