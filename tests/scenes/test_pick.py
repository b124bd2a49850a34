"""`pick`: the top of the highest object, walls with normals, free floor and the nearest point, on a
synthetic room whose geometry is known, and through the CLI on a built-in scene."""

from __future__ import annotations

import json

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.scenes import Splats
from splatplan.robots.footprint import robot_footprint
from splatplan.scenes.pick import PickConfig, pick_points

#: the room: a 4 x 4 m floor at z = 0, a wall along x = 1.9 (x from 1.9 to 1.96, 1 m tall), a box of
#: 40 x 40 cm with its top at z = 0.6 centred at (-1, -1), a 2 cm thin rail (top z = 0.8) at y = 1.5;
#: the wall is 6 cm thick (three cells of 2 cm: its faces are one wall)
BOX_CENTRE, BOX_HALF, BOX_TOP = np.array([-1.0, -1.0]), 0.2, 0.6
WALL_X = 1.9


def _room(seed: int = 0, faint_floater: bool = False) -> Splats:
    rng = np.random.default_rng(seed)
    parts = [np.c_[rng.uniform(-2, 2, (40000, 2)), rng.normal(0.0, 0.002, 40000)]]  # floor
    top = np.c_[rng.uniform(-BOX_HALF, BOX_HALF, (4000, 2)) + BOX_CENTRE, np.full(4000, BOX_TOP)]
    side = np.c_[np.full(3000, BOX_CENTRE[0] + BOX_HALF), rng.uniform(-1.2, -0.8, 3000), rng.uniform(0, BOX_TOP, 3000)]
    parts += [top, side, np.c_[np.full(3000, BOX_CENTRE[0] - BOX_HALF), rng.uniform(-1.2, -0.8, 3000), rng.uniform(0, BOX_TOP, 3000)]]
    for x in (WALL_X, WALL_X + 0.06):  # the wall's two faces
        parts.append(np.c_[np.full(8000, x), rng.uniform(-2, 2, 8000), rng.uniform(0, 1.0, 8000)])
    parts.append(np.c_[rng.uniform(-1.5, 1.0, 3000), rng.uniform(1.49, 1.51, 3000), np.full(3000, 0.8)])  # the rail's top
    means = np.concatenate(parts)
    n = len(means)
    op = np.full(n, 0.9)
    if faint_floater:
        means = np.concatenate([means, [[0.0, 0.0, 1.5]]])
        op = np.concatenate([op, [0.05]])
        n += 1
    return Splats(means, np.tile([1.0, 0, 0, 0], (n, 1)), np.full((n, 3), 0.01), op, np.full((n, 3), 0.5))


@pytest.fixture(scope="module")
def room() -> Splats:
    return _room(faint_floater=True)


def test_top_is_the_box_not_the_thin_rail_nor_a_faint_splat(room):
    res = pick_points(room, PickConfig(cell=0.02))
    assert res.floor.found and abs(res.floor.z) < 0.02
    top = res.top
    assert top is not None
    assert top.point[2] == pytest.approx(BOX_TOP, abs=0.01)  # the rail (0.8) is 2 cm wide: no surface; the floater is faint
    assert np.all(np.abs(top.point[:2] - BOX_CENTRE) < BOX_HALF - 0.05)  # well inside the top, not at its edge
    assert top.area == pytest.approx((2 * BOX_HALF) ** 2, rel=0.25)


def test_wall_point_and_normal_face_the_reference(room):
    q = np.array([1.0, 0.5, 0.4])
    res = pick_points(room, PickConfig(cell=0.02), near=q)
    wall = min(res.walls, key=lambda w: w.distance)
    np.testing.assert_allclose(wall.normal, [-1, 0, 0], atol=0.05)  # faces the point, on the -x side
    assert wall.point[0] == pytest.approx(WALL_X, abs=0.03)  # the face toward the point, not the far one
    assert wall.point[1] == pytest.approx(q[1], abs=0.05) and wall.point[2] == pytest.approx(q[2], abs=0.01)
    assert wall.length == pytest.approx(4.0, rel=0.05) and wall.z[1] == pytest.approx(1.0, abs=0.05)
    assert sum(abs(w.point[0] - WALL_X) < 0.2 for w in res.walls) == 1  # both faces are one wall
    near = res.near
    assert near is not None and near.distance == pytest.approx(0.4, abs=0.02)  # the floor under q (the wall is 0.9 away)
    np.testing.assert_allclose(near.point[:2], q[:2], atol=0.05)
    np.testing.assert_allclose(near.normal, [0, 0, 1], atol=0.05)  # up, toward q


def test_free_floor_avoids_obstacles_by_the_footprint(room):
    from splatplan.robots import load_robot

    go2 = load_robot("go2")
    height, radius = robot_footprint(go2)
    assert 0.3 < height < 0.7 and 0.3 < radius < 0.7
    res = pick_points(room, PickConfig(cell=0.02), footprint=(height, radius))
    free = res.free
    assert free is not None and free.radius == radius and len(free.cells)
    c = free.cells
    # no free cell lets the footprint reach an opaque mean between the step and the robot's height
    # (the box's sides, the wall; less the cell's half diagonal: a mean lies anywhere in its cell)
    from scipy.spatial import cKDTree

    m = room.means[(room.opacities >= 0.5) & (room.means[:, 2] > 0.05) & (room.means[:, 2] < height)]
    gap, _ = cKDTree(m[:, :2]).query(c)
    assert gap.min() >= radius - 0.02 * np.sqrt(0.5)
    assert gap.min() < radius + 0.05  # and the free floor reaches up to them
    assert np.all(np.abs(c) <= 2.0 - radius + 0.02)  # the floor's edge (unknown beyond) bounds it too
    # the rail stands at 0.8, above the Go2: it does not block the floor under it
    assert np.any(np.abs(c[:, 1] - 1.5) < 0.02)
    point = pick_points(room, PickConfig(cell=0.02, height=1.0)).free
    assert point is not None and point.radius == 0
    under = (np.abs(point.cells[:, 1] - 1.5) < 0.01) & (point.cells[:, 0] > -1.4) & (point.cells[:, 0] < 0.9)
    assert not under.any()  # a taller clearance: the rail blocks the floor under it


def test_object_capture_has_no_free_floor_and_an_arm_is_refused():
    rng = np.random.default_rng(1)
    m = np.c_[rng.normal(0, 0.1, (5000, 2)), rng.uniform(0.3, 0.5, 5000)]  # a blob with no floor under it
    blob = Splats(m, np.tile([1.0, 0, 0, 0], (5000, 1)), np.full((5000, 3), 0.01), np.full(5000, 0.9), np.full((5000, 3), 0.5))
    res = pick_points(blob, PickConfig(floor_z=0.0))
    assert not res.floor.found and res.free is None
    from splatplan.robots import load_robot

    with pytest.raises(SplatplanError, match="fixed-base arm"):
        robot_footprint(load_robot("panda"))
    with pytest.raises(SplatplanError, match="opacity"):
        pick_points(blob, PickConfig(opacity_min=1.0))


def test_pick_is_rigid_in_x_y(room):
    """Shifting the scene in x, y shifts every point by the same amount (the grid follows the means)."""
    shift = np.array([3.0, -2.0, 0.0])
    moved = Splats(room.means + shift, room.quats, room.scales, room.opacities, room.colors)
    a, b = pick_points(room, PickConfig(cell=0.02)), pick_points(moved, PickConfig(cell=0.02))
    assert a.top is not None and b.top is not None
    np.testing.assert_allclose(b.top.point, a.top.point + shift, atol=1e-4)


def test_cli_pick_on_a_builtin_scene(tmp_path, capsys):
    from splatplan.cli import main

    ply = tmp_path / "apartment.ply"
    assert main(["scene", "apartment", "--out", str(ply)]) == 0
    out = tmp_path / "picks.json"
    assert main(["pick", str(ply), "--robot", "go2", "--near", "0.5,0.1,0.3", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "top " in text and "wall " in text and "free " in text and "--goal-pose " in text
    d = json.loads(out.read_text())
    assert d["robot"] == "go2" and d["floor"]["found"]
    assert d["top"]["point"][2] == pytest.approx(1.15, abs=0.03)  # the fridge and the wardrobe: 1.15 m
    walls = d["walls"]
    assert any(abs(w["normal"][1]) > 0.99 and abs(abs(w["point"][1]) - 2.95) < 0.05 for w in walls)  # an outer wall at y = +-3
    assert d["free_floor"]["regions"] and d["free_floor"]["radius"] > 0.3
    # bad input: one line, exit 2, nothing written
    bad = tmp_path / "bad.json"
    assert main(["pick", str(ply), "--robot", "panda", "--json", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("splatplan: error:") and "fixed-base arm" in err[0] and not bad.exists()
    assert main(["pick", str(ply), "--near", "1,2"]) == 2
    assert "--near" in capsys.readouterr().err
