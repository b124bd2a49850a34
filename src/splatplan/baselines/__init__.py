"""The four baselines of the paper's comparison, one module each, in PyTorch like the originals.

PyTorch is an optional extra: nothing in the core imports this package, and importing it without
torch raises a one-line :class:`~splatplan.errors.SplatplanError` naming
``pip install 'splatplan[baselines]'``.

All read the same splat arrays (means, **wxyz** quats, linear scales, opacities) and a robot
sphere (centre, radius). Each module provides

* ``<name>_score(splats_or_tensors, centers, radius, device="auto", **method_kw) -> (B,)`` - the
  method's native score (see each module and SPEC section 3),
* ``collision_score(...)`` - the same, oriented so that **larger = more likely in collision**
  (for precision-recall threshold sweeps),
* ``collision_from_score(native_score)`` - the method's own binary decision,
* a class holding the preprocessed scene tensors (``SplatNav(splats, device).score(c, r)``, ...)
  with ``score``, ``collision_score`` and ``in_collision`` methods.

:data:`BASELINES` maps a name to a :class:`BaselineInfo`.

========== ================================== ====================== ===================== =====
name       native score                       collision_score        native collision      batch
========== ================================== ====================== ===================== =====
splatnav   min_i max_t K_i(t)                 -score                 score < 1             1
safersplat min_i (phi_i d_i^2 - r^2)          -score                 score < 0             1
atlasnav   min_i (|p-mu_i| - 3 sigma_i - r)   -score                 score < 0             4096
splanning  p = 1 - exp(-I / 4 pi)             p                      p > alpha (0.01)      4096
========== ================================== ====================== ===================== =====
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from ..errors import SplatplanError

try:  # the baselines are PyTorch code; torch is the optional extra splatplan[baselines]
    import torch  # noqa: F401
except ImportError:
    raise SplatplanError("the baselines need PyTorch, which is not installed: pip install 'splatplan[baselines]'") from None

from . import atlasnav, safersplat, splanning, splatnav
from ._common import SceneTensors, as_scene_tensors
from .atlasnav import AtlasNav, atlasnav_score
from .safersplat import SaferSplat, safersplat_score
from .splanning import Splanning, splanning_score
from .splatnav import SplatNav, splatnav_score


@dataclass(frozen=True)
class BaselineInfo:
    """One registry entry."""

    name: str  #: registry key
    cls: type  #: class holding the scene tensors: ``cls(splats, device, **kw)``
    score: Callable[..., Any]  #: native score function ``score(splats, centers, radius, device, **kw)``
    collision_score: Callable[..., Any]  #: oriented score (larger = collision), same signature
    collision_from_score: Callable[..., Any]  #: native decision from the native score
    native_batch: int  #: queries per evaluation in the original code base
    #: value of ``collision_score`` at the native decision boundary (collision iff above; for
    #: Splat-Nav and SPLANNING the decision is strict: ``>`` -1 resp. ``>`` alpha)
    collision_threshold: float


BASELINES: dict[str, BaselineInfo] = {
    name: BaselineInfo(name, cls, score, mod.collision_score, mod.collision_from_score, cls.native_batch, cls.collision_threshold())
    for name, mod, cls, score in (
        ("splatnav", splatnav, SplatNav, splatnav_score),
        ("safersplat", safersplat, SaferSplat, safersplat_score),
        ("atlasnav", atlasnav, AtlasNav, atlasnav_score),
        ("splanning", splanning, Splanning, splanning_score),
    )
}

__all__ = [
    "BASELINES",
    "BaselineInfo",
    "SceneTensors",
    "as_scene_tensors",
    "SplatNav",
    "SaferSplat",
    "AtlasNav",
    "Splanning",
    "splatnav_score",
    "safersplat_score",
    "atlasnav_score",
    "splanning_score",
]
