"""Scene stage: the Splats container, readers/writers, filters, transforms and built-in scenes."""

from .splats import SH_C0, Splats, quat_to_rotmat, rotmat_to_quat

__all__ = ["SH_C0", "Splats", "quat_to_rotmat", "rotmat_to_quat"]
