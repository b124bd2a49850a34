"""Metric stage: the CollisionSplatting distance (Warp kernel + numpy reference)."""

from .blockers import Blockers
from .checker import CollisionChecker
from .config import MetricConfig, QueryResult
from .interop import MetricWorkspace

__all__ = ["Blockers", "CollisionChecker", "MetricConfig", "MetricWorkspace", "QueryResult", "TierConfig"]


def __getattr__(name: str):
    if name == "TierConfig":  # lives beside the kernels: importing it loads Warp
        from .wp_metric import TierConfig

        return TierConfig
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
