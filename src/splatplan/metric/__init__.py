"""Metric stage: the CollisionSplatting distance (Warp kernel + numpy reference)."""

from .blockers import Blockers
from .checker import CollisionChecker
from .config import MetricConfig, QueryResult
from .interop import MetricWorkspace
from .tiers import TierConfig

__all__ = ["Blockers", "CollisionChecker", "MetricConfig", "MetricWorkspace", "QueryResult", "TierConfig"]

