"""splatplan: collision-aware motion planning directly in 3D Gaussian Splatting scenes.

Public API (imported lazily so ``splatplan --help`` stays fast):

* :func:`load_scene` / :func:`save_scene` - read any supported splat file / write INRIA ``.ply`` or ``.spz``.
* :class:`Splats` - the scene container (means, wxyz quats, linear scales, opacities, colours).
* :class:`CollisionChecker`, :class:`MetricConfig`, :class:`QueryResult` - the CollisionSplatting metric.
* :func:`build_stonehenge` - the built-in scene (splats + exact analytic ground truth).
* :func:`plan`, :class:`RRT`, :class:`MPPI` (+ configs) - planners on the metric.
* :mod:`render` - the rendering package (:func:`splatplan.render.render`, :class:`RenderResult`, :class:`Camera`).
"""

from __future__ import annotations

import importlib

#: The package version (semantic versioning; the one place it is set: pyproject.toml reads it). See CHANGELOG.md.
__version__ = "0.2.0"

#: public name -> (module, attribute; None: the module itself)
_LAZY = {
    "Splats": ("splatplan.scenes.splats", "Splats"),
    "load_scene": ("splatplan.scenes.load", "load_scene"),
    "save_scene": ("splatplan.scenes.load", "save_scene"),
    "CollisionChecker": ("splatplan.metric.checker", "CollisionChecker"),
    "MetricConfig": ("splatplan.metric.config", "MetricConfig"),
    "QueryResult": ("splatplan.metric.config", "QueryResult"),
    "SplatplanError": ("splatplan.errors", "SplatplanError"),
    "PlanningError": ("splatplan.errors", "PlanningError"),
    "build_stonehenge": ("splatplan.scenes.builtin.stonehenge", "build_stonehenge"),
    "plan": ("splatplan.planners", "plan"),
    "RRT": ("splatplan.planners", "RRT"),
    "RRTConfig": ("splatplan.planners", "RRTConfig"),
    "MPPI": ("splatplan.planners", "MPPI"),
    "MPPIConfig": ("splatplan.planners", "MPPIConfig"),
    "Robot": ("splatplan.robots", "Robot"), "load_robot": ("splatplan.robots", "load_robot"),
    "load_encoder": ("splatplan.encoders", "load_encoder"),
    "render": ("splatplan.render", None), "RenderResult": ("splatplan.render", "RenderResult"), "Camera": ("splatplan.render", "Camera"),
}

__all__ = sorted(_LAZY) + ["__version__"]


def __getattr__(name: str):
    if name in _LAZY:
        mod, attr = _LAZY[name]
        module = importlib.import_module(mod)
        return module if attr is None else getattr(module, attr)
    raise AttributeError(f"module 'splatplan' has no attribute {name!r}")
