"""Browser viewer (optional extra ``splatplan[viewer]``): splats, robot, conservatism, plans.

Nothing in the library's stages imports this package; it is a layer on top of them.
"""

from __future__ import annotations

from .app import SplatViewer, ViewerConfig
from .ports import free_port, port_free

__all__ = ["SplatViewer", "ViewerConfig", "free_port", "port_free"]
