"""The one encoder interface, input/output conversion, and the image cost.

Images are ``(B, H, W, 3)`` RGB in [0, 1] (float; ``uint8`` is divided by 255), as a numpy array or
a torch tensor; every function returns the same kind it was given (numpy float32, or a torch tensor
on the input's device). Values outside [0, 1] are clamped (a 3DGS render is clamped at 0 only).
Gradients flow to a torch input that requires them; otherwise encoders run under ``no_grad``.

Cost (paper Sec. II-D): ``image_cost(e_t, e_r) = ||e_t - e_r||^2`` per row. :class:`EmbeddingDistance`
adds the combined form the paper's authors use, with global (CLS) and patch-token terms::

    cost = w_global * ||g_t - g_r||^2 + w_patch * mean_p ||tok_t,p - tok_r,p||^2
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .._warp import resolve_torch_device
from ..errors import SplatplanError


def require(module: str, extra: str = "vision", what: str = "image encoders"):
    """Import an optional dependency or raise a one-line :class:`SplatplanError` naming the extra."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise SplatplanError(f"{what} need the Python package {module!r}: pip install 'splatplan[{extra}]'") from None


if TYPE_CHECKING:
    import torch
else:
    torch = require("torch")


def size_hw(image_size: int | tuple[int, int]) -> tuple[int, ...]:
    """An image size given as one side or (H, W) -> (H, W) ints (length unchecked: callers validate)."""
    if isinstance(image_size, (int, float)):
        return (int(image_size), int(image_size))
    return tuple(int(v) for v in image_size)


# ------------------------------------------------------------------------------ array kinds
@dataclass(frozen=True)
class _Kind:
    """Where an input came from, so that outputs can be returned as the same kind."""

    is_torch: bool
    device: Any = None

    def back(self, t: "torch.Tensor"):
        if self.is_torch:
            return t.to(self.device)
        return t.detach().to("cpu", torch.float32).numpy()


def images_to_torch(images: Any, device: "torch.device") -> tuple["torch.Tensor", _Kind]:
    """(B, H, W, 3) numpy/torch RGB -> (B, 3, H, W) float32 in [0, 1] on ``device``, and its kind.

    Raises :class:`SplatplanError` for a wrong shape, a wrong channel count, a non-numeric dtype or
    non-finite values (checked on host inputs; device tensors are not synchronised to check).
    """
    x: Any  # the torch tensor or the numpy array until converted below
    if torch.is_tensor(images):
        kind = _Kind(True, images.device)
        x = images
    else:
        kind = _Kind(False)
        try:
            x = np.asarray(images)
        except Exception as exc:  # ragged lists and the like
            raise SplatplanError(f"images: cannot read as an array ({exc.__class__.__name__}: {exc})") from None
    shape = tuple(x.shape)
    if len(shape) != 4:
        hint = " (add a batch axis: images[None])" if len(shape) == 3 else ""
        raise SplatplanError(f"images: expected shape (B, H, W, 3), got {shape}{hint}")
    if shape[-1] != 3:
        hint = "; drop or composite the alpha channel first" if shape[-1] == 4 else ""
        raise SplatplanError(f"images: expected 3 RGB channels in the last axis, got {shape[-1]} (shape {shape}){hint}")
    if shape[1] < 1 or shape[2] < 1:
        raise SplatplanError(f"images: height and width must be >= 1, got {shape}")
    if kind.is_torch:
        if x.dtype == torch.uint8:
            x = x.to(device=device, dtype=torch.float32) / 255.0
        elif x.is_floating_point():
            if x.device.type == "cpu" and x.numel() and not bool(torch.isfinite(x).all()):
                raise SplatplanError("images contain NaN or Inf")
            x = x.to(device=device, dtype=torch.float32)
        else:
            raise SplatplanError(f"images: expected float in [0, 1] or uint8, got dtype {x.dtype}")
    else:
        if x.dtype == np.uint8:
            x = torch.from_numpy(np.ascontiguousarray(x)).to(device=device, dtype=torch.float32) / 255.0
        elif np.issubdtype(x.dtype, np.floating):
            if x.size and not np.isfinite(x).all():
                raise SplatplanError("images contain NaN or Inf")
            x = torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32)).to(device)
        else:
            raise SplatplanError(f"images: expected float in [0, 1] or uint8, got dtype {x.dtype}")
    return x.clamp(0.0, 1.0).permute(0, 3, 1, 2), kind  # (B, 3, H, W)


def _emb_to_torch(e: Any, what: str) -> tuple["torch.Tensor", _Kind]:
    if torch.is_tensor(e):
        return e, _Kind(True, e.device)
    a = np.asarray(e)
    if not np.issubdtype(a.dtype, np.number):
        raise SplatplanError(f"{what}: expected a numeric array, got dtype {a.dtype}")
    return torch.from_numpy(np.ascontiguousarray(a, dtype=np.float32)), _Kind(False)


def image_cost(target_emb: Any, rendered_emb: Any):
    """Squared embedding distance ``||e_t - e_r||^2`` per rendered image (paper Sec. II-D).

    Args:
        target_emb: (D,) one target, or (B, D) one target per row (or (1, D), broadcast).
        rendered_emb: (B, D) embeddings of the rendered images.

    Returns:
        (B,) costs, the same kind (numpy / torch) as ``rendered_emb``.
    """
    t, _ = _emb_to_torch(target_emb, "target embedding")
    r, kind = _emb_to_torch(rendered_emb, "rendered embedding")
    if r.ndim != 2:
        raise SplatplanError(f"rendered embedding: expected shape (B, D), got {tuple(r.shape)}")
    if t.ndim == 1:
        t = t[None]
    if t.ndim != 2 or t.shape[1] != r.shape[1] or t.shape[0] not in (1, r.shape[0]):
        raise SplatplanError(f"target embedding of shape {tuple(t.shape)} does not match rendered embeddings {tuple(r.shape)}: expected (D,), (1, D) or (B, D)")
    t = t.to(device=r.device, dtype=r.dtype)
    return kind.back(((t - r) ** 2).sum(dim=1))


def token_cost(target_tok: "torch.Tensor", rendered_tok: "torch.Tensor") -> "torch.Tensor":
    """``mean_p ||tok_t,p - tok_r,p||^2`` for (B or 1, P, D) target and (B, P, D) rendered tokens -> (B,)."""
    if target_tok.shape[1:] != rendered_tok.shape[1:]:
        raise SplatplanError(f"patch tokens of shape {tuple(target_tok.shape)} and {tuple(rendered_tok.shape)} differ: encode target and rendered images at the same image_size")
    return ((target_tok - rendered_tok) ** 2).sum(dim=2).mean(dim=1)


# ------------------------------------------------------------------------------ the interface
class Encoder:
    """An image encoder: ``encode(images (B, H, W, 3) in [0, 1]) -> (B, dim)``.

    Attributes:
        name: an honest identifier that every output using the encoder prints, e.g.
            ``"dinov2-vits14"``, ``"dinov2-vits14-RANDOM-WEIGHTS"``, ``"thumbnail16-weight-free"``.
        dim: length D of the global embedding.
        description: one line saying what the embedding is.
        has_tokens: whether :meth:`encode_tokens` is available.
        image_size: (H, W) the images are resized to before encoding (pixels).

    Subclasses implement ``_forward(x (b, 3, H, W) in [0, 1] on self.device, tokens: bool)
    -> (global (b, dim), tokens (b, P, Dt) or None)``; this class handles conversion, batching,
    gradients and optional L2 normalisation.
    """

    name: str = "encoder"
    dim: int = 0
    description: str = ""
    has_tokens: bool = False
    image_size: tuple[int, int] = (224, 224)
    model: Any  # the torch model of the encoders that have one (None once closed)

    def __init__(self, *, device: Any = "auto", batch_size: int = 32, normalize: bool = False) -> None:
        if int(batch_size) < 1:
            raise SplatplanError(f"batch_size must be >= 1, got {batch_size}")
        self.device = resolve_torch_device(device)
        self.batch_size = int(batch_size)
        self.normalize = bool(normalize)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, dim={self.dim}, image_size={self.image_size}, device={self.device})"

    # -- subclasses
    def _forward(self, x: "torch.Tensor", tokens: bool) -> tuple["torch.Tensor", "torch.Tensor | None"]:
        raise NotImplementedError

    # -- public
    def features(self, images: Any, tokens: bool = False):
        """Global embedding (B, dim) and, when ``tokens``, patch tokens (B, P, Dt), one forward pass."""
        if tokens and not self.has_tokens:
            raise SplatplanError(f"encoder {self.name} has no patch tokens; use the global embedding only (w_patch = 0)")
        x, kind = images_to_torch(images, self.device)
        g, t = self._features_torch(x, tokens)
        return kind.back(g), (kind.back(t) if t is not None else None)

    def _features_torch(self, x: "torch.Tensor", tokens: bool) -> tuple["torch.Tensor", "torch.Tensor | None"]:
        """:meth:`features` of images already converted by :func:`images_to_torch`: x (B, 3, H, W) on
        ``self.device`` -> torch tensors (callers check ``has_tokens``)."""
        with torch.set_grad_enabled(bool(x.requires_grad)):
            gs: list[torch.Tensor] = []
            ts: list[torch.Tensor] = []
            for i in range(0, x.shape[0], self.batch_size):
                g, t = self._forward(x[i : i + self.batch_size], tokens)
                gs.append(g)
                if tokens:
                    assert t is not None  # (_forward returns tokens when asked)
                    ts.append(t)
            if x.shape[0] == 0:
                g = x.new_zeros((0, self.dim))
                t = x.new_zeros((0, 0, 0)) if tokens else None
            else:
                g = torch.cat(gs)
                t = torch.cat(ts) if tokens else None
            if self.normalize:
                g = torch.nn.functional.normalize(g, dim=-1)
                t = torch.nn.functional.normalize(t, dim=-1) if t is not None else None
        return g, t

    def encode(self, images: Any):
        """(B, H, W, 3) RGB in [0, 1] -> (B, dim) embeddings (same kind as the input)."""
        return self.features(images, tokens=False)[0]

    def encode_tokens(self, images: Any):
        """(B, H, W, 3) RGB in [0, 1] -> (B, P, Dt) patch tokens (same kind as the input)."""
        return self.features(images, tokens=True)[1]

    def image_cost(self, target_emb: Any, rendered_emb: Any):
        """``||e_t - e_r||^2`` per row: target (D,) or (B, D), rendered (B, D) -> (B,). See :func:`image_cost`."""
        return image_cost(target_emb, rendered_emb)

    def close(self) -> None:
        """Release the model (and device memory). The encoder cannot be used afterwards."""
        if hasattr(self, "model"):
            self.model = None

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class EmbeddingDistance:
    """The distance in an encoder's embedding between fixed target image(s) and batches of renders
    (the image term of the paper's objective; :class:`splatplan.planners.ImageCost` is the planner's
    cost term that renders each rollout and calls this).

    ``cost(rendered) = w_global * ||g_t - g_r||^2 + w_patch * mean_p ||tok_t,p - tok_r,p||^2``
    with g the encoder's global embedding (CLS for DINOv2) and tok its patch tokens. Target
    features are computed once here. Both images are resized to the encoder's ``image_size``, so
    the patch grids match whatever the render resolution.

    Args:
        encoder: an :class:`Encoder`.
        target_images: (H, W, 3), (1, H, W, 3) or (B, H, W, 3) (one target per rendered row).
        w_global: weight of the global-embedding distance (>= 0).
        w_patch: weight of the mean patch-token distance (>= 0; needs ``encoder.has_tokens``).
        normalize: L2-normalise the global embedding and every patch token before the distances
            (cosine distance, ``2 - 2 cos`` in [0, 4]), so the cost scale is the same for every encoder
            whatever the magnitude of its features.
    """

    def __init__(self, encoder: Encoder, target_images: Any, w_global: float = 1.0, w_patch: float = 0.0, normalize: bool = False) -> None:
        if not (np.isfinite(w_global) and np.isfinite(w_patch)) or w_global < 0 or w_patch < 0 or w_global + w_patch <= 0:
            raise SplatplanError(f"image cost weights must be finite, >= 0 and not both 0, got w_global={w_global}, w_patch={w_patch}")
        if w_patch > 0 and not encoder.has_tokens:
            raise SplatplanError(f"encoder {encoder.name} has no patch tokens: use w_patch = 0 or a DINOv2 / EfficientNet encoder")
        self.encoder, self.w_global, self.w_patch = encoder, float(w_global), float(w_patch)
        tgt = target_images
        if (torch.is_tensor(tgt) or isinstance(tgt, np.ndarray)) and tgt.ndim == 3:
            tgt = tgt[None]
        x, _ = images_to_torch(tgt, encoder.device)
        self.normalize = bool(normalize)
        g, t = self._features(x)
        self.target_global, self.target_tokens = g.detach(), (t.detach() if t is not None else None)  # (Bt, D), (Bt, P, Dt)

    def _features(self, x: "torch.Tensor"):
        g, t = self.encoder._features_torch(x, tokens=self.w_patch > 0)
        if self.normalize:
            g = torch.nn.functional.normalize(g, dim=-1)
            t = torch.nn.functional.normalize(t, dim=-1) if t is not None else None
        return g, t

    def __call__(self, rendered_images: Any):
        """(B, H, W, 3) renders in [0, 1] -> (B,) costs (same kind as the input)."""
        x, kind = images_to_torch(rendered_images, self.encoder.device)
        bt = self.target_global.shape[0]
        if bt not in (1, x.shape[0]):
            raise SplatplanError(f"{bt} target images for {x.shape[0]} rendered images: give one target or one per rendered image")
        g, t = self._features(x)
        cost = self.w_global * ((self.target_global - g) ** 2).sum(dim=1) if self.w_global > 0 else g.new_zeros(g.shape[0])
        if self.w_patch > 0:
            assert self.target_tokens is not None and t is not None  # (tokens asked for: w_patch > 0)
            cost = cost + self.w_patch * token_cost(self.target_tokens, t)
        return kind.back(cost)
