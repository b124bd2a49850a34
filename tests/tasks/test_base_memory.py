"""The Go2 base planner's sensed-obstacle memory (``BaseConfig.memory``): the occupancy grid, the
geodesic field against its slow reference, the sensor's line of sight (against a dense-sampling
and a metric reference; a wall hides what is behind it until the base drives around it), and a
U-trap that only the memory gets out of."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

H = 0.6  # wall height (m); the Go2 stands ~0.45 m tall


def _scene(walls):
    """A TaskScene of 0.1 m thick walls ((x0, y0, x1, y1) segments, metres, z up) plus two small
    posts at (-3, -3) and (3.5, 3) that set the scene box; splats sampled on the boxes."""
    from splatplan.metric import CollisionChecker
    from splatplan.scenes.builtin.primitives import AnalyticScene, SurfaceSplatConfig, make_box, splats_from_boxes
    from splatplan.tasks._common import TaskScene

    boxes = []
    for x0, y0, x1, y1 in walls:
        c = ((x0 + x1) / 2, (y0 + y1) / 2, H / 2)
        boxes.append(make_box(c, (max(abs(x1 - x0) / 2, 0.05), max(abs(y1 - y0) / 2, 0.05), H / 2)))
    boxes += [make_box((-3.0, -3.0, 0.05), (0.05, 0.05, 0.05)), make_box((3.5, 3.0, 0.05), (0.05, 0.05, 0.05))]
    gt = AnalyticScene(np.stack(boxes), ["wall"] * len(boxes))
    splats = splats_from_boxes(gt, 6000, config=SurfaceSplatConfig(floater_fraction=0.0), seed=0)
    return TaskScene("walls", splats, CollisionChecker(splats, n_sigma=0.75), gt)


@pytest.fixture(scope="module")
def go2():
    from splatplan.tasks.base import load_go2

    return load_go2()


def test_grid_marks_a_wall_blocked_and_free_space_free(go2):
    from splatplan.planners.memory import ObstacleMemory

    ts = _scene([(1.0, -1.5, 1.0, 1.5)])  # a wall along y at x = 1
    lo, hi = ts.splats.bounds()
    mem = ObstacleMemory(go2, ts.checker, lo, hi, goal=(2.5, 0.0), cell=0.1, radius=2.0, occlusion=False)  # the whole disc
    assert not mem.blocked.any() and not mem.sensed.any()  # unknown = free
    field0 = mem.field.copy()
    assert mem.sense(np.array([0.0, 0.0])) > 0
    at = lambda x, y: tuple(np.floor((np.array([x, y]) - mem.origin) / mem.cell).astype(int))  # noqa: E731
    assert mem.blocked[at(1.0, 0.0)] and mem.blocked[at(1.0, 1.0)]  # on the wall
    assert not mem.blocked[at(0.0, 0.0)] and not mem.blocked[at(-1.0, 1.0)] and mem.sensed[at(-1.0, 1.0)]  # free space
    assert not mem.sensed[at(2.5, 0.0)] and not mem.sensed[at(-2.9, -2.9)]  # beyond the radius: unknown
    d = np.linalg.norm(mem.centers - [0.0, 0.0], axis=-1)
    assert mem.sensed[d <= 2.0].all() and not mem.sensed[d > 2.0 + 1e-9].any()
    # the base's own footprint: blocked cells are exactly those where every heading collides
    idx = np.argwhere(mem.sensed)[::7]
    xy = mem.centers[idx[:, 0], idx[:, 1]]
    q = np.concatenate([np.repeat(xy, len(mem.yaws), 0), np.tile(mem.yaws, len(xy))[:, None]], axis=1)
    every = np.asarray(ts.checker.collides_robot(go2, q)).any(-1).reshape(len(xy), -1).all(axis=1)
    np.testing.assert_array_equal(mem.blocked[idx[:, 0], idx[:, 1]], every)
    # memoised: sensing again from the same place checks nothing
    n = mem.stats["n_queries"]
    assert mem.sense(np.array([0.0, 0.0])) == 0 and mem.stats["n_queries"] == n
    # the field now goes around the wall: behind it, farther than before
    assert mem.distance(np.array([0.0, 0.0])) > field0[at(0.0, 0.0)] + 0.5


def test_geodesic_around_a_wall_is_longer_than_the_straight_line():
    from splatplan.planners.memory import geodesic_field

    blocked = np.zeros((40, 30), bool)
    blocked[20, 3:] = True  # a wall at x = 2.05 from y = 0.3 up, gap below
    goal = np.array([3.0, 2.0])
    f = geodesic_field(blocked, (0.0, 0.0), 0.1, goal)
    ctr = lambda i, j: (np.array([i, j]) + 0.5) * 0.1  # noqa: E731
    straight = np.linalg.norm(ctr(10, 20) - goal)
    around = np.linalg.norm(ctr(10, 20) - ctr(19, 1)) + np.linalg.norm(ctr(21, 1) - goal)  # through the gap
    assert f[10, 20] > straight + 1.0 and f[10, 20] >= around - 0.05
    assert f[10, 20] <= 1.09 * (around + 0.2)  # 8-connected paths are at most ~8% longer than straight ones
    # open space: 8-connected distance between the straight line and 1.083x it
    o = geodesic_field(np.zeros((40, 30), bool), (0.0, 0.0), 0.1, goal)
    e = np.linalg.norm(np.stack(np.meshgrid(np.arange(40), np.arange(30), indexing="ij"), -1) * 0.1 + 0.05 - goal, axis=-1)
    assert np.all(o >= e - 0.1 - 1e-9) and np.all(o <= 1.083 * e + 0.15)
    # blocked cells read no closer to the goal than the free cells next to them
    assert f[20, 20] >= min(f[19, 20], f[21, 20])


@pytest.mark.parametrize("seed", range(6))
def test_geodesic_field_matches_the_reference(seed):
    from splatplan.planners.memory import _geodesic_field_reference, geodesic_field

    rng = np.random.default_rng(seed)
    nx, ny = rng.integers(1, 14, 2)
    blocked = rng.random((nx, ny)) < rng.uniform(0.0, 0.6)
    origin, cell = rng.uniform(-1, 1, 2), rng.uniform(0.05, 0.3)
    goal = origin + rng.random(2) * np.array([nx, ny]) * cell
    cost = None if seed % 2 else 1.0 + 2.0 * rng.random((nx, ny))
    np.testing.assert_allclose(geodesic_field(blocked, origin, cell, goal, cost), _geodesic_field_reference(blocked, origin, cell, goal, cost), rtol=1e-9, atol=1e-9)


def test_memory_escapes_a_u_trap_that_plain_mppi_does_not(go2):
    from splatplan.tasks.base import BaseConfig, run_base

    # a U open to the left; the base starts inside, the goal lies behind the U's bottom
    ts = _scene([(1.0, -1.1, 1.0, 1.1), (-1.5, 1.1, 1.0, 1.1), (-1.5, -1.1, 1.0, -1.1)])
    cfg = BaseConfig(max_steps=90, ground_z=None)
    start, goal = (0.0, 0.0, 0.0), (2.5, 0.0)
    plain = run_base(go2, ts, goal, start=start, config=cfg)
    mem = run_base(go2, ts, goal, start=start, config=replace(cfg, memory=True))
    assert not plain.success and plain.final_position_error_m > 1.0 and plain.min_clearance_m > 0
    assert mem.success and mem.min_clearance_m > 0, (mem.final_position_error_m, mem.min_clearance_m)
    assert mem.extra["memory"]["n_blocked"] > 0 and mem.extra["memory"]["sense_s"] < mem.time_s


@pytest.mark.parametrize("seed", range(4))
def test_line_of_sight_matches_dense_sampling_of_the_segment(seed):
    from splatplan.planners.memory import line_of_sight

    rng = np.random.default_rng(seed)
    opaque = rng.random((30, 24)) < rng.uniform(0.02, 0.15)  # (MX, MY) squares of res
    origin, res = rng.uniform(-1, 1, 2), 0.05
    size = np.array(opaque.shape) * res
    p0 = origin + rng.uniform(0.1, 0.9, 2) * size
    p1 = origin + rng.uniform(-0.1, 1.1, (200, 2)) * size  # some end outside the grid (clear there)
    end = [0.0, 0.1, 0.07, 0.3][seed]
    fast = line_of_sight(opaque, origin, res, p0, p1, end=end)
    ref = []
    for q in p1:
        L = np.linalg.norm(q - p0)
        t = np.linspace(0.0, 1.0 - end / L, 4000) if L > end else np.zeros(0)
        ij = np.floor((p0 + t[:, None] * (q - p0) - origin) / res).astype(int)
        ok = (ij >= 0).all(1) & (ij < opaque.shape).all(1)
        ref.append(not opaque[ij[ok, 0], ij[ok, 1]].any())
    ref = np.asarray(ref)
    assert not (fast & ~ref).any()  # every sampled point of a visible segment lies in a clear square
    assert (fast == ref).mean() >= 0.97, (fast == ref).mean()  # the rest: corner clips between samples
    assert line_of_sight(np.ones((4, 4), bool), (0.0, 0.0), 0.05, (0.1, 0.1), np.array([[0.12, 0.1], [0.18, 0.1]]), end=0.05).tolist() == [True, False]


def test_line_of_sight_is_conservative_against_the_metric_along_the_segment(go2):
    from splatplan.planners.memory import ObstacleMemory, _line_of_sight_reference, line_of_sight

    ts = _scene([(1.0, -1.5, 1.0, 1.5), (-1.0, 0.8, -0.2, 0.8)])
    lo, hi = ts.splats.bounds()
    mem = ObstacleMemory(go2, ts.checker, lo, hi, goal=(2.5, 0.0), cell=0.1, radius=2.5)
    rng = np.random.default_rng(1)
    p0, tg = np.array([0.0, 0.3]), rng.uniform([-1.5, -2.0], [2.2, 2.0], (120, 2))
    mem._sense_opacity(p0, 3.0)
    fast = line_of_sight(mem.opaque, mem.origin, mem.sight_res, p0, tg, end=mem.cell)
    ref = _line_of_sight_reference(ts.checker, mem.sensor_height, p0, tg, end=mem.cell)
    assert not (fast & ~ref).any()  # visible implies the metric finds every point of the segment free
    assert 10 < fast.sum() < len(tg) - 10, fast.sum()
    # ... and it is conservative by at most the squares' size: a square is opaque when its
    # circumscribed sphere (radius res / sqrt 2) meets a splat, so a segment whose points are free by
    # the metric for spheres of sqrt(2) res (+ the reference's sample spacing) is visible
    big = _line_of_sight_reference(ts.checker, mem.sensor_height, p0, tg, end=mem.cell, radius=np.sqrt(2.0) * mem.sight_res + 0.005)
    assert not (big & ~fast).any(), int((big & ~fast).sum())
    assert big.sum() >= 0.9 * fast.sum(), (big.sum(), fast.sum())  # the bound is not vacuous


def test_a_wall_hides_the_cells_behind_it_until_the_base_drives_around_it(go2):
    from splatplan.planners.memory import ObstacleMemory

    ts = _scene([(1.0, -1.5, 1.0, 1.5)])  # a wall along y at x = 1, y in [-1.5, 1.5]
    lo, hi = ts.splats.bounds()
    mem = ObstacleMemory(go2, ts.checker, lo, hi, goal=(2.5, 0.0), cell=0.1, radius=2.0)
    at = lambda x, y: tuple(np.floor((np.array([x, y]) - mem.origin) / mem.cell).astype(int))  # noqa: E731
    mem.sense(np.array([0.0, 0.0]))
    assert mem.sensed[at(-1.0, 1.0)] and not mem.blocked[at(-1.0, 1.0)] and mem.sensed[at(0.5, -1.0)]  # in the open: sensed
    assert not mem.sensed[at(1.5, 0.0)] and not mem.sensed[at(1.8, 0.5)] and not mem.blocked[1 + at(1.0, 0.0)[0] :].any()  # behind the wall: unknown
    # the wall's near side is seen: on every row along the wall a blocked cell in front of it, so the field goes around
    rows = range(at(0.0, -1.4)[1], at(0.0, 1.4)[1] + 1)
    assert all(mem.blocked[at(0.7, 0.0)[0] : at(1.0, 0.0)[0] + 1, j].any() for j in rows)
    assert mem.distance(np.array([0.0, 0.0])) > np.linalg.norm([2.5, 0.0]) + 1.0
    n_unseen = int((~mem.sensed & (np.linalg.norm(mem.centers, axis=-1) <= 2.0)).sum())
    assert n_unseen > 50 and mem.stats["n_occluded"] == n_unseen
    q = mem.stats["n_queries"]
    mem.sense(np.array([0.0, 0.0]))  # nothing new in sight: no robot queries (the hidden cells are only ray-tested)
    assert mem.stats["n_queries"] == q and mem.stats["n_occluded"] == 2 * n_unseen
    for y in np.arange(0.0, 2.3, 0.4):  # drive up past the wall's end and around it
        mem.sense(np.array([0.0, y]))
    assert not mem.sensed[at(1.5, 0.0)]
    for x in np.arange(0.4, 2.0, 0.4):
        mem.sense(np.array([x, 2.2]))
    mem.sense(np.array([1.8, 1.0]))
    assert mem.sensed[at(1.5, 0.0)] and mem.sensed[at(1.8, 0.5)] and not mem.blocked[at(1.8, 0.5)]
    assert mem.blocked[at(1.2, 0.0)]  # and now the far side of the wall


def test_memory_maps_reach_the_plot_not_the_json():
    """The sensed grid travels in TaskResult.maps (drawn by plot_run), never into result JSON."""
    import json

    import numpy as np

    from splatplan.tasks._common import TaskResult
    from splatplan.tasks.plot import _draw_memory

    blocked = np.zeros((4, 3), bool)
    blocked[1, 1] = True
    sensed = np.ones((4, 3), bool)
    maps = {"memory_blocked": blocked, "memory_sensed": sensed, "memory_origin": np.array([-0.2, -0.1]), "memory_cell": 0.1}
    res = TaskResult(success=True, trajectory=np.zeros((2, 3)), min_clearance_m=0.1, final_position_error_m=0.0, time_s=1.0, steps_per_s=1.0,
                     collision_cost=True, clearance_source="analytic", maps=maps)  # fmt: skip
    d = res.to_json()
    assert "maps" not in d
    json.dumps(d)  # serialisable
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    _draw_memory(ax, maps)
    img = ax.images[0]
    assert np.allclose(img.get_extent(), [-0.2, 0.2, -0.1, 0.2])  # (4, 3) cells of 0.1 m from the corner
    labels = [h.get_label() for h in ax.get_lines()]
    assert "sensed blocked (memory)" in labels and "sensed free (memory)" in labels
    plt.close(fig)


def test_recovery_sweeps_out_of_the_u_trap_through_the_strategy(go2):
    """The stagnation recovery (StructuredDrives, off by default) starts a sweep in the U trap: the
    goal cost switches to the sweep term and back, every event is recorded, no run error."""
    from splatplan.planners.drive import DriveGoalCost
    from splatplan.planners.costs import Rollout
    from splatplan.tasks.base import BaseConfig, run_base

    ts = _scene([(1.0, -1.1, 1.0, 1.1), (-1.5, 1.1, 1.0, 1.1), (-1.5, -1.1, 1.0, -1.1)])
    cfg = BaseConfig(max_steps=30, ground_z=None, recovery=True, stuck_steps=4, recovery_min_distance_m=0.1)
    r = run_base(go2, ts, (2.5, 0.0), start=(0.0, 0.0, 0.0), config=cfg)
    events = [e["event"] for e in r.extra["events"]]
    assert "detour" in events and r.min_clearance_m > 0, events
    # the sweep term: progress along the swept heading is rewarded, the goal term still reported
    cost = DriveGoalCost((2.5, 0.0))
    states = np.zeros((2, 3, 3))
    states[1, :, 1] = [0.1, 0.2, 0.3]  # sample 1 walks along +y, facing +x
    ro = Rollout(states, np.zeros((2, 3, 3)), 0.2)
    goal_only = cost.evaluate(ro)
    cost.sweep = (np.pi / 2, np.zeros(2))
    swept = cost.evaluate(ro)
    assert set(goal_only.terms) == {"goal"} and set(swept.terms) == {"sweep"}
    assert swept.terms["sweep"][1] < swept.terms["sweep"][0]
    np.testing.assert_array_equal(swept.values["goal_cost"], goal_only.terms["goal"])
