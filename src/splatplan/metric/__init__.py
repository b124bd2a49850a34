"""Metric stage: the CollisionSplatting distance (Warp kernel + numpy reference)."""

from .checker import CollisionChecker
from .config import MetricConfig, QueryResult

__all__ = ["CollisionChecker", "MetricConfig", "QueryResult"]
