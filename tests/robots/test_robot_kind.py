"""A robot says what it is (``Robot.base``, ``Robot.walks_on_terrain``, ``Robot.is_point``), for
built-ins and URDFs alike; nothing reads its name to find out."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.robots import load_robot, parse_robot_name

from .ground_robot import BODY_AXES, write_ground_robot


@pytest.mark.parametrize(
    "name, base, walks, point",
    [("panda", "fixed", False, False), ("go2", "planar", True, False), ("sphere:0.02", "translation", False, True), ("ellipsoid:0.03,0.02,0.01", "translation", False, True)],
)
def test_builtins_say_what_they_are(name, base, walks, point):
    r = load_robot(name)
    assert (r.base, r.walks_on_terrain, r.is_point) == (base, walks, point)
    assert r.describe()["base"] == base and r.describe()["walks_on_terrain"] == walks
    assert pickle.loads(pickle.dumps(r)).walks_on_terrain == walks
    assert r.inflated(0.01).walks_on_terrain == walks


def test_a_planar_point_body_is_not_a_point_and_does_not_walk():
    r = load_robot("ellipsoid:0.03,0.015,0.012", base="planar")
    assert (r.base, r.walks_on_terrain, r.is_point) == ("planar", False, False)


def test_urdf_is_a_fixed_base_unless_told(tmp_path):
    urdf = write_ground_robot(tmp_path)
    r = load_robot(urdf)
    assert (r.base, r.walks_on_terrain, r.dof) == ("fixed", False, 0)
    planar = load_robot(f"{urdf}:planar")
    assert (planar.base, planar.walks_on_terrain, planar.joint_names) == ("planar", False, ["x", "y", "yaw"])
    assert planar.base_pose[2, 3] == 0.0  # a planar base that does not walk stays where its URDF puts it
    assert load_robot(urdf, base="translation").is_point  # a rigid body translating: a point robot


def test_a_walking_urdf_stands_on_the_floor_like_go2(tmp_path):
    urdf = write_ground_robot(tmp_path)
    walker = load_robot(f"{urdf}:walking")
    same = load_robot(urdf, walks_on_terrain=True)
    for r in (walker, same):
        assert (r.base, r.walks_on_terrain, r.joint_names) == ("planar", True, ["x", "y", "yaw"])
        assert r.base_pose[2, 3] == pytest.approx(BODY_AXES[2])  # lowest ellipsoid point at z = 0
        assert r.info["standing_height_m"] == pytest.approx(BODY_AXES[2])
    c, _, ax = walker.ellipsoids(np.zeros(3))
    assert c[0, 2] - ax[0, 2] == pytest.approx(0.0, abs=1e-12)
    go2 = load_robot("go2")
    c, r = go2.ellipsoid_frames(go2.q_default)
    assert np.min(c[:, 2] - np.linalg.norm(r[:, 2, :] * go2.semi_axes, axis=-1)) == pytest.approx(0.0, abs=1e-12)
    # a base pose places the floor frame as given (no second raise), as for go2
    pose = np.eye(4)
    pose[2, 3] = 0.3
    assert load_robot(f"{urdf}:walking", base_pose=pose).base_pose[2, 3] == pytest.approx(0.3)


def test_robot_at_keeps_a_walking_urdfs_standing_offset(tmp_path):
    from splatplan.cli._common import parse_base_pose, robot_at

    urdf = write_ground_robot(tmp_path)
    spec = f"{urdf}:walking"
    moved = robot_at(spec, parse_base_pose("0.5,0,0.1"))
    assert moved.walks_on_terrain
    np.testing.assert_allclose(moved.base_pose[:3, 3], [0.5, 0.0, BODY_AXES[2] + 0.1])
    go2 = robot_at("go2", parse_base_pose("0.5,0,0.1"))
    np.testing.assert_allclose(go2.base_pose[:3, 3], [0.5, 0.0, load_robot("go2").base_pose[2, 3] + 0.1])


def test_suffix_names_and_their_errors(tmp_path):
    urdf = write_ground_robot(tmp_path)
    p = parse_robot_name(f"{urdf}:walking")
    assert (p.kind, p.path, p.base, p.walks_on_terrain) == ("path", str(urdf), "planar", True)
    assert parse_robot_name(str(urdf)).path == str(urdf)
    with pytest.raises(SplatplanError, match="base"):
        load_robot(f"{urdf}:walking", base="fixed")
    with pytest.raises(SplatplanError, match="planar base"):
        load_robot(urdf, walks_on_terrain=True, base="translation")
    with pytest.raises(SplatplanError, match="walks_on_terrain"):
        load_robot(f"{urdf}:planar", walks_on_terrain=True)
    assert not load_robot("go2", walks_on_terrain=False).walks_on_terrain
    # a file whose name itself ends in ":walking" is that file
    odd = tmp_path / "odd"
    odd.mkdir()
    write_ground_robot(odd).rename(odd / "x.urdf:walking")
    (odd / "crawler.ellipsoids.yaml").rename(odd / "x.urdf:walking.ellipsoids.yaml")
    assert parse_robot_name(odd / "x.urdf:walking").base is None
