"""DINOv2 ViT encoders through ``transformers.Dinov2Model``, from a local weights folder.

Weights cannot be downloaded on this machine. A weights folder is what
``Dinov2Model.from_pretrained("facebook/dinov2-small").save_pretrained(DIR)`` writes on a machine
with internet access: ``config.json`` plus ``model.safetensors`` (or ``pytorch_model.bin``).
Without weights, ``random_init=True`` builds the same architecture with random weights (seeded,
without touching the global torch RNG); its name ends in ``-RANDOM-WEIGHTS`` so no output can pass
it off as DINOv2.

Preprocessing (torch): bilinear antialiased resize of the whole image to ``image_size`` (square 224
by default, no crop; a multiple of the 14-pixel patch), then ImageNet mean/std. The model
interpolates its position embeddings to the grid, so 224 gives 16 x 16 = 256 patch tokens.
Embeddings come from the last layer after the final LayerNorm: ``cls`` (the CLS token),
``mean`` (mean of the patch tokens) or ``cls_mean`` (both concatenated, 2D); patch tokens are
(B, P, D).
"""

from __future__ import annotations

import json
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from ..errors import SplatplanError
from .base import Encoder, require, size_hw, torch
from .preprocess import imagenet_normalize, resize

#: Architectures by name: Dinov2Config fields and the Hugging Face repository with the weights.
ARCHS: dict[str, dict[str, Any]] = {
    "dinov2-vits14": dict(hidden_size=384, num_hidden_layers=12, num_attention_heads=6, hub="facebook/dinov2-small"),
    "dinov2-vitb14": dict(hidden_size=768, num_hidden_layers=12, num_attention_heads=12, hub="facebook/dinov2-base"),
    "dinov2-vitl14": dict(hidden_size=1024, num_hidden_layers=24, num_attention_heads=16, hub="facebook/dinov2-large"),
    # tests and benchmarks only: a small model of the same design, always random
    "dinov2-tiny": dict(hidden_size=48, num_hidden_layers=2, num_attention_heads=3, hub=None),
}
_CHECKED = ("hidden_size", "num_hidden_layers", "num_attention_heads")
POOLINGS = ("cls", "mean", "cls_mean")
PATCH = 14


def dinov2_config(arch: str):
    """The ``Dinov2Config`` of a named architecture (patch 14, MLP ratio 4, 518-pixel position grid)."""
    transformers = require("transformers", what="DINOv2 encoders")
    a = {k: v for k, v in ARCHS[arch].items() if k != "hub"}
    return transformers.Dinov2Config(patch_size=PATCH, mlp_ratio=4, image_size=518, use_swiglu_ffn=False, **a)


def _arch_of(cfg: dict) -> str | None:
    for name, a in ARCHS.items():
        if all(cfg.get(k) == a[k] for k in _CHECKED) and cfg.get("patch_size", PATCH) == PATCH:
            return name
    return None


def _get_hint(arch: str) -> str:
    hub = ARCHS.get(arch, {}).get("hub") or "facebook/dinov2-small"
    return (f"put the Hugging Face weights of {hub} there: on a machine with internet run "
            f"`transformers.Dinov2Model.from_pretrained('{hub}').save_pretrained(DIR)` and copy DIR here "
            f"(config.json + model.safetensors); for tests use random_init=True / --encoder-random-init")


@contextmanager
def _quiet_transformers():
    """No progress bar or load report from transformers while loading; its settings are restored after."""
    tl = require("transformers.utils.logging", what="DINOv2 encoders")
    verbosity, bar = tl.get_verbosity(), tl.is_progress_bar_enabled()
    tl.set_verbosity_error()
    tl.disable_progress_bar()
    try:
        yield
    finally:
        tl.set_verbosity(verbosity)
        if bar:
            tl.enable_progress_bar()


def load_dinov2_model(weights: str | Path | None, arch: str = "dinov2"):
    """Load a ``Dinov2Model`` from a local folder and check its architecture.

    Args:
        weights: folder with ``config.json`` and ``model.safetensors`` / ``pytorch_model.bin``.
        arch: a name in :data:`ARCHS` the folder must hold, or ``"dinov2"`` for any DINOv2.

    Returns:
        (model, arch name or ``None`` when it matches no named architecture).
    """
    if weights is None:
        raise SplatplanError(f"{arch} needs a weights folder (weights=DIR / --encoder-weights DIR): {_get_hint(arch)}")
    d = Path(weights)
    if not d.exists():
        raise SplatplanError(f"{arch} weights folder {d} does not exist: {_get_hint(arch)}")
    if not d.is_dir():
        raise SplatplanError(f"{arch} weights {d} is a file, expected a folder with config.json and model.safetensors: {_get_hint(arch)}")
    cfg_path = d / "config.json"
    if not cfg_path.is_file():
        raise SplatplanError(f"{arch} weights folder {d} has no config.json: {_get_hint(arch)}")
    try:
        cfg = json.loads(cfg_path.read_text())
        if not isinstance(cfg, dict):
            raise ValueError("not a JSON object")
    except (ValueError, UnicodeDecodeError) as exc:
        raise SplatplanError(f"{cfg_path} is not a readable JSON config ({exc})") from None
    if cfg.get("model_type") != "dinov2":
        raise SplatplanError(f"weights folder {d} holds a {cfg.get('model_type')!r} model, not DINOv2 (model_type 'dinov2'): {_get_hint(arch)}")
    found = _arch_of(cfg)
    if arch != "dinov2" and found != arch:
        got = ", ".join(f"{k} {cfg.get(k)}" for k in _CHECKED)
        want = ", ".join(f"{k} {ARCHS[arch][k]}" for k in _CHECKED)
        raise SplatplanError(f"weights folder {d} holds {found or 'an unnamed DINOv2'} ({got}), not {arch} ({want}): use --encoder {found or 'dinov2'} or the right folder")
    files = ("model.safetensors", "pytorch_model.bin", "model.safetensors.index.json", "pytorch_model.bin.index.json")
    if not any((d / f).is_file() for f in files):
        raise SplatplanError(f"weights folder {d} has config.json but no model.safetensors or pytorch_model.bin: {_get_hint(found or arch)}")
    transformers = require("transformers", what="DINOv2 encoders")
    try:
        with _quiet_transformers():
            model, info = transformers.Dinov2Model.from_pretrained(str(d), local_files_only=True, output_loading_info=True)
    except Exception as exc:  # transformers raises many types for broken files
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else exc.__class__.__name__
        raise SplatplanError(f"cannot load DINOv2 weights from {d}: {msg[:300]}") from None
    missing = [k for k in info.get("missing_keys", []) if "mask_token" not in k]
    bad = info.get("mismatched_keys", [])
    if missing or bad:
        first = (missing or [str(b) for b in bad])[0]
        raise SplatplanError(f"weights in {d} do not fit the DINOv2 architecture of its config.json ({len(missing)} missing, {len(bad)} mismatched tensors, e.g. {first})")
    return model, found


class Dinov2Encoder(Encoder):
    """A DINOv2 ``Dinov2Model`` behind the :class:`~splatplan.encoders.base.Encoder` interface.

    Build with :meth:`from_weights`, :meth:`random`, or directly from a ``Dinov2Model``.

    Args:
        model: a ``transformers.Dinov2Model``.
        name: the name every output shows.
        pooling: ``cls`` | ``mean`` | ``cls_mean`` (global embedding; see module docstring).
        image_size: side (or (H, W)) in pixels the images are resized to; multiples of 14.
    """

    has_tokens = True

    def __init__(self, model, name: str, *, pooling: str = "cls", image_size: int | tuple[int, int] = 224,
                 device: Any = "auto", batch_size: int = 32, normalize: bool = False) -> None:
        super().__init__(device=device, batch_size=batch_size, normalize=normalize)
        if pooling not in POOLINGS:
            raise SplatplanError(f"DINOv2 pooling {pooling!r} unknown: use one of {', '.join(POOLINGS)}")
        hw = size_hw(image_size)
        patch = int(model.config.patch_size)
        if len(hw) != 2 or min(hw) < patch or any(v % patch for v in hw) or max(hw) > 2048:
            raise SplatplanError(f"DINOv2 image_size {image_size}: expected a multiple of the {patch}-pixel patch between {patch} and 2048 (e.g. 224)")
        self.model = model.eval().requires_grad_(False).to(self.device)
        self.pooling, self.image_size = pooling, hw
        d = int(model.config.hidden_size)
        self.dim = 2 * d if pooling == "cls_mean" else d
        self.token_dim = d
        self.n_tokens = (hw[0] // patch) * (hw[1] // patch)
        self.name = name
        self.description = f"{name}: {pooling} embedding of a {hw[0]}x{hw[1]} image, {self.n_tokens} patch tokens of dim {d}"

    @classmethod
    def from_weights(cls, weights: str | Path | None, arch: str = "dinov2-vits14", **kw) -> "Dinov2Encoder":
        """Load from a local Hugging Face folder; ``arch`` is checked against its ``config.json``."""
        if arch != "dinov2" and arch not in ARCHS:
            raise SplatplanError(f"unknown DINOv2 architecture {arch!r}: use one of {', '.join(ARCHS)} or 'dinov2'")
        if arch == "dinov2-tiny":
            raise SplatplanError("dinov2-tiny exists only with random weights (random_init=True); it is for tests and benchmarks")
        model, found = load_dinov2_model(weights, arch)
        c = model.config
        name = found or f"dinov2-h{c.hidden_size}-l{c.num_hidden_layers}-p{c.patch_size}"
        return cls(model, name, **kw)

    @classmethod
    def random(cls, arch: str = "dinov2-vits14", seed: int = 0, **kw) -> "Dinov2Encoder":
        """The architecture with random weights (seeded; the global torch RNG is left as it was)."""
        if arch not in ARCHS:
            raise SplatplanError(f"unknown DINOv2 architecture {arch!r}: use one of {', '.join(ARCHS)}")
        transformers = require("transformers", what="DINOv2 encoders")
        cfg = dinov2_config(arch)
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            model = transformers.Dinov2Model(cfg)
        return cls(model, f"{arch}-RANDOM-WEIGHTS", **kw)

    def _forward(self, x: "torch.Tensor", tokens: bool):
        x = imagenet_normalize(resize(x, self.image_size))
        h = self.model(pixel_values=x).last_hidden_state  # (b, 1 + P, D): CLS then patches, after LayerNorm
        cls_tok, patches = h[:, 0], h[:, 1:]
        if self.pooling == "cls":
            g = cls_tok
        elif self.pooling == "mean":
            g = patches.mean(dim=1)
        else:
            g = torch.cat([cls_tok, patches.mean(dim=1)], dim=1)
        return g, (patches if tokens else None)
