"""Robots as collision ellipsoids on a kinematic tree (stage: robot).

* :func:`load_robot` - built-ins ("panda", "go2", "sphere:R", "ellipsoid:A,B,C") or any URDF; a new
  Robot on every call. :func:`parse_robot_name` is the one parser of those names
  (:data:`ROBOT_NAME_HELP` their one help text); :data:`DEFAULT_POINT_ROBOT` the studies' sphere.
* :class:`Robot` - one type for every robot: numpy reference FK (``link_poses``, ``ellipsoids``),
  a Warp FK kernel (``fk_wp``, CPU multi-core or CUDA), joint limits, a motion bound per joint,
  conservative self-collision; what kind of robot it is (``base``: :data:`BaseKind`,
  ``walks_on_terrain``, ``is_point``), which code asks instead of its name.
* :func:`fit_model` / :func:`mvee` - enclosing ellipsoids fitted to link meshes; YAML I/O.
"""

from .builtin import (
    DEFAULT_POINT_ROBOT,
    KNOWN,
    ROBOT_NAME_HELP,
    RobotName,
    load_robot,
    parse_robot_name,
    point_radius,
)
from .fit import EllipsoidSet, fit_model, load_yaml, mvee, save_yaml
from .robot import BaseKind, Robot
from .urdf import read_srdf, read_urdf

__all__ = [
    "DEFAULT_POINT_ROBOT", "KNOWN", "ROBOT_NAME_HELP", "BaseKind", "EllipsoidSet", "Robot", "RobotName", "fit_model", "load_robot", "load_yaml", "mvee",
    "parse_robot_name", "point_radius", "read_srdf", "read_urdf", "save_yaml",
]  # fmt: skip
