"""Robots as collision ellipsoids on a kinematic tree (stage: robot).

* :func:`load_robot` - built-ins ("panda", "go2", "sphere:R", "ellipsoid:A,B,C") or any URDF.
* :class:`Robot` - one type for every robot: numpy reference FK (``link_poses``, ``ellipsoids``),
  a Warp FK kernel (``fk_wp``, CPU multi-core or CUDA), joint limits, a motion bound per joint,
  conservative self-collision.
* :func:`fit_model` / :func:`mvee` - enclosing ellipsoids fitted to link meshes; YAML I/O.
"""

from .builtin import KNOWN, load_robot
from .fit import EllipsoidSet, fit_model, load_yaml, mvee, save_yaml
from .robot import Robot
from .urdf import read_srdf, read_urdf

__all__ = ["KNOWN", "EllipsoidSet", "Robot", "fit_model", "load_robot", "load_yaml", "mvee", "read_srdf", "read_urdf", "save_yaml"]
