"""Scene stage: the Splats container, readers/writers, filters, transforms, built-in scenes and the
safety margin from the splat spacing (:func:`margin_for`)."""

from . import transforms
from .filters import FilterReport, filter_floaters
from .load import SCENE_EXTENSIONS, load_scene, save_scene
from .margin import SplatMargin, margin_for
from .splats import SH_C0, Splats, quat_to_rotmat, rotmat_to_quat
from .moveit import load_moveit_request, load_moveit_scene
from .builtin.analytic_scene import AnalyticScene
from .builtin.surface_splats import SurfaceSplatConfig, splats_from_boxes, splats_from_scene
from .builtin.stonehenge import StonehengeLayout, build_stonehenge, ground_truth_path, plot_top_view, stonehenge_layout, write_stonehenge

__all__ = [
    "AnalyticScene",
    "StonehengeLayout",
    "SurfaceSplatConfig",
    "build_stonehenge",
    "ground_truth_path",
    "plot_top_view",
    "splats_from_boxes",
    "splats_from_scene",
    "load_moveit_request",
    "load_moveit_scene",
    "stonehenge_layout",
    "write_stonehenge",
    "SCENE_EXTENSIONS",
    "SH_C0",
    "SplatMargin",
    "FilterReport",
    "Splats",
    "filter_floaters",
    "load_scene",
    "margin_for",
    "quat_to_rotmat",
    "rotmat_to_quat",
    "save_scene",
    "transforms",
]
