"""Shared fixtures: a small tree-shaped URDF exercising every joint type and geometry kind."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

TREE_URDF = """<?xml version="1.0"?>
<robot name="tree">
  <link name="base">
    <collision><origin xyz="0 0 0.05" rpy="0.1 0.2 0.3"/><geometry><box size="0.3 0.2 0.1"/></geometry></collision>
  </link>
  <link name="l1">
    <collision><origin xyz="0.02 0 0.15" rpy="0.4 -0.2 0.1"/><geometry><cylinder radius="0.04" length="0.3"/></geometry></collision>
  </link>
  <link name="l2">
    <collision><origin xyz="0 0.05 0"/><geometry><sphere radius="0.03"/></geometry></collision>
  </link>
  <link name="l3">
    <collision><origin xyz="0.1 0 0" rpy="0 1.5707963 0"/><geometry><capsule radius="0.03" length="0.15"/></geometry></collision>
  </link>
  <link name="l4">
    <collision><origin xyz="0.05 0.01 0.02" rpy="0.3 0.2 -0.5"/><geometry><mesh filename="meshes/part.stl" scale="1.0 0.8 1.2"/></geometry></collision>
  </link>
  <link name="l5">
    <collision><origin xyz="0 0 0"/><geometry><box size="0.05 0.05 0.05"/></geometry></collision>
  </link>
  <link name="l6"/>
  <link name="l7">
    <collision><origin xyz="0 0 0.02"/><geometry><sphere radius="0.02"/></geometry></collision>
  </link>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="l1"/><origin xyz="0.1 0 0.1" rpy="0 0 0.2"/>
    <axis xyz="0.3 0.5 0.8"/><limit lower="-2" upper="2" velocity="1.5" effort="1"/>
  </joint>
  <joint name="j2" type="prismatic">
    <parent link="l1"/><child link="l2"/><origin xyz="0 0 0.3" rpy="0.5 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-0.1" upper="0.2" velocity="0.5" effort="1"/>
  </joint>
  <joint name="j3" type="continuous">
    <parent link="l1"/><child link="l3"/><origin xyz="0 0.05 0.25" rpy="0 0.3 0"/>
    <axis xyz="1 0 0"/><limit velocity="2.0" effort="1"/>
  </joint>
  <joint name="j4" type="revolute">
    <parent link="l3"/><child link="l4"/><origin xyz="0.2 0 0" rpy="0 0 0.7"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" velocity="1" effort="1"/>
    <mimic joint="j1" multiplier="-0.5" offset="0.3"/>
  </joint>
  <joint name="j5" type="fixed">
    <parent link="base"/><child link="l5"/><origin xyz="-0.1 0.05 0.12" rpy="0.1 0 0"/>
  </joint>
  <joint name="j6" type="revolute">
    <parent link="l5"/><child link="l6"/><origin xyz="0 0 0.05" rpy="0 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-1" upper="1" velocity="1" effort="1"/>
  </joint>
  <joint name="j7" type="fixed">
    <parent link="l6"/><child link="l7"/><origin xyz="0 0 0.1" rpy="0 0.4 0"/>
  </joint>
</robot>
"""


#: the MotionBenchMaker Panda beside the repository (tests using it skip when it is absent)
MBM = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "mbm" / "panda"


def inside_union(pts: np.ndarray, ells) -> np.ndarray:
    """(N,) bool: each point lies in at least one ellipsoid (centre, rotation, semi-axes) of ``ells``."""
    from splatplan.robots.fit import mahalanobis

    ok = np.zeros(len(pts), dtype=bool)
    for e in ells:
        ok |= mahalanobis(pts, *e) <= 1.0
    return ok


def write_tree(folder: Path, with_mesh: bool = True) -> Path:
    import trimesh

    (folder / "meshes").mkdir(exist_ok=True)
    if with_mesh:
        m = trimesh.creation.capsule(height=0.12, radius=0.025, count=[8, 8])
        m.apply_transform(trimesh.transformations.rotation_matrix(0.7, [1, 1, 0]))
        m.export(folder / "meshes" / "part.stl")
    p = folder / "tree.urdf"
    p.write_text(TREE_URDF)
    return p


@pytest.fixture(scope="session")
def tree_urdf(tmp_path_factory) -> Path:
    return write_tree(tmp_path_factory.mktemp("tree"))


@pytest.fixture(scope="session")
def tree_robot(tree_urdf):
    from splatplan.robots import load_robot

    return load_robot(tree_urdf, fit_method="split")  # kinematics under test here, not the (slower) default fit


@pytest.fixture(scope="session")
def panda():
    from splatplan.robots import load_robot

    return load_robot("panda")


@pytest.fixture(scope="session")
def go2():
    from splatplan.robots import load_robot

    return load_robot("go2")


def random_q(robot, n: int, seed: int = 0, span: float = 2.0) -> np.ndarray:
    """Uniform configurations within the limits (infinite limits -> [-span, span])."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.joint_limits.T
    lo = np.where(np.isfinite(lo), lo, -span)
    hi = np.where(np.isfinite(hi), hi, span)
    return rng.uniform(lo, hi, size=(n, robot.dof))


def devices() -> list[str]:
    from splatplan._warp import wp

    return ["cpu"] + (["cuda:0"] if wp().is_cuda_available() else [])
