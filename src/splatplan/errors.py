"""Error types. Everything the user can cause raises :class:`SplatplanError` (a ``ValueError``).

The CLI turns these into a one-line message on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations


class SplatplanError(ValueError):
    """Bad input or an impossible request. The message names the problem and what to do."""


class SceneFormatError(SplatplanError):
    """A scene file is broken, truncated, of an unknown format or misses required fields."""


class PlanningError(SplatplanError):
    """A planning request cannot be served (start or goal in collision, empty box, ...)."""
