"""Analytic primitives of the built-in scenes, in one import: the names of four modules.

* :mod:`.primitive_sdf`: primitive rows (``make_box``, ``make_cylinder``, ``make_sphere``) and
  their exact signed distances;
* :mod:`.ellipsoid_clearance`: clearance of solid ellipsoids to the primitives;
* :mod:`.analytic_scene`: :class:`AnalyticScene` (a union of primitives, its SDF and JSON);
* :mod:`.surface_splats`: the surface splat sampler (:func:`splats_from_scene`).

Code inside the package imports from the defining modules; this module keeps the names where
scripts have always found them (``from splatplan.scenes.builtin.primitives import AnalyticScene``).
"""

from __future__ import annotations

from .analytic_scene import JSON_FORMAT, JSON_VERSION, AnalyticScene, box_aabbs, primitive_aabbs
from .ellipsoid_clearance import ellipsoid_clearance_chunk, fibonacci_sphere, project_to_ellipsoid
from .primitive_sdf import (
    box_corners,
    box_sdf,
    box_sdf_local,
    boxes_sdf_dense,
    curved_sdf,
    cylinder_sdf,
    cylinder_sdf_local,
    make_box,
    make_cylinder,
    make_sphere,
    sphere_sdf,
    yaw_quat,
)
from .surface_splats import FACE_NAMES, SurfaceSplatConfig, copy_splats, n_splats_for_spacing, sample_faces, splats_from_boxes, splats_from_scene

__all__ = [
    "FACE_NAMES", "JSON_FORMAT", "JSON_VERSION", "AnalyticScene", "SurfaceSplatConfig", "box_aabbs", "box_corners", "box_sdf",
    "box_sdf_local", "boxes_sdf_dense", "copy_splats", "curved_sdf", "cylinder_sdf", "cylinder_sdf_local", "ellipsoid_clearance_chunk",
    "fibonacci_sphere", "make_box", "make_cylinder", "make_sphere", "n_splats_for_spacing", "primitive_aabbs", "project_to_ellipsoid",
    "sample_faces", "sphere_sdf", "splats_from_boxes", "splats_from_scene", "yaw_quat",
]  # fmt: skip
