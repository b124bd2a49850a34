"""A tiny ground robot as a URDF (one box-shaped body and its collision ellipsoid in a sidecar
YAML), for tests of what a robot says it is: loaded as a path it is a fixed base; as
``PATH.urdf:walking`` (or ``walks_on_terrain=True``) a planar base that walks on terrain, like go2."""

from __future__ import annotations

from pathlib import Path

#: the body's ellipsoid semi-axes (metres): a 40 x 24 x 16 cm box-like body
BODY_AXES = (0.2, 0.12, 0.08)

URDF = """<?xml version="1.0"?>
<robot name="crawler">
  <link name="body">
    <collision><geometry><box size="0.34 0.2 0.14"/></geometry></collision>
  </link>
</robot>
"""

ELLIPSOIDS = f"""robot: crawler
urdf: crawler
ellipsoids:
- link: body
  center: [0.0, 0.0, 0.0]
  quat: [1.0, 0.0, 0.0, 0.0]
  semi_axes: [{BODY_AXES[0]}, {BODY_AXES[1]}, {BODY_AXES[2]}]
"""


def write_ground_robot(folder: Path) -> Path:
    """``folder/crawler.urdf`` with its ``crawler.ellipsoids.yaml`` beside it (no fitting at load)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "crawler.ellipsoids.yaml").write_text(ELLIPSOIDS)
    p = folder / "crawler.urdf"
    p.write_text(URDF)
    return p
