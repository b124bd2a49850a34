"""Visual reaching: the terminal image cost term (shape, ordering, one render per evaluation) and a
tiny MPPI run with the wrist camera."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.planners import ImageCost, MPPIConfig, Rollout
from splatplan.render import SplatRenderer

robots = pytest.importorskip("splatplan.robots")


@pytest.fixture(scope="module")
def setup():
    from splatplan.encoders import load_encoder
    from splatplan.tasks._common import load_task_scene
    from splatplan.planners.reach_goals import reach_start
    from splatplan.render.cameras import wrist_camera

    robot = robots.load_robot("panda")
    ts = load_task_scene("tabletop", n_splats=20_000)
    cam = wrist_camera(robot, image_size=24)
    q0 = reach_start(robot)
    with SplatRenderer(ts.splats, "cpu") as rend:
        yield robot, ts, cam, q0, rend, load_encoder("thumbnail", image_size=8)


def test_image_cost_shape_and_ordering(setup):
    robot, ts, cam, q0, rend, enc = setup
    goal = q0 + np.array([0.15, 0.1, -0.1, 0.1, 0.0, -0.1, 0.2])
    target = np.asarray(cam.render(rend, robot, goal[None], background=(0.5,) * 3).rgb[0])
    cost = ImageCost(rend, cam, robot, enc, target, weight=2.0, background=(0.5,) * 3, w_empty=1.0)
    # K = 5 rollouts of horizon 3; the one ending at the goal must be cheapest
    ends = np.stack([goal, q0, goal + 0.25, goal - 0.25, q0 + np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.5])])
    states = np.repeat(ends[:, None, :], 3, axis=1)
    states[:, 0] = q0
    roll = Rollout(states, np.zeros((5, 3, 7)), 0.05)
    n0 = cost.n_renders
    c = cost(roll)
    assert c.shape == (5,) and c.dtype == np.float64 and np.all(np.isfinite(c))
    assert cost.n_renders == n0 + 1  # one batched render for the whole batch
    assert int(np.argmin(c)) == 0 and c[0] < 1e-3
    np.testing.assert_allclose(c, cost.cost_of_states(ends), atol=1e-6)
    # the cost only looks at the chosen time step (terminal by default)
    at0 = Rollout(roll.states, roll.controls, roll.dt, goal_step=0)  # a shrinking horizon names the goal step
    assert np.allclose(cost(at0), cost(at0)[0])


def test_image_cost_log_transform(setup):
    robot, ts, cam, q0, rend, enc = setup
    goal = q0 + np.array([0.15, 0.1, -0.1, 0.1, 0.0, -0.1, 0.2])
    target = np.asarray(cam.render(rend, robot, goal[None], background=(0.5,) * 3).rgb[0])
    ends = np.stack([goal, q0, goal + 0.1, goal - 0.2])
    kw = dict(weight=2.0, background=(0.5,) * 3, w_empty=1.0)
    raw = ImageCost(rend, cam, robot, enc, target, **kw).cost_of_states(ends) / 2.0
    logc = ImageCost(rend, cam, robot, enc, target, log_eps=0.01, **kw)
    c = logc.cost_of_states(ends)
    value = logc.evaluate(Rollout(ends[:, None], np.zeros((4, 1, 7)), 0.1))  # the raw costs are reported, not stored
    np.testing.assert_allclose(value.values["image_raw"], raw, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(value.terms["image"], c, rtol=1e-9)
    np.testing.assert_allclose(c, 2.0 * np.log1p(raw / 0.01), rtol=1e-6, atol=1e-9)
    assert np.array_equal(np.argsort(c), np.argsort(raw))  # monotone: same ranking of the samples
    with pytest.raises(SplatplanError, match="log_eps"):
        ImageCost(rend, cam, robot, enc, target, log_eps=-1.0)


def test_image_cost_bad_inputs(setup):
    robot, ts, cam, q0, rend, enc = setup
    with pytest.raises(SplatplanError, match="RGB"):
        ImageCost(rend, cam, robot, enc, np.zeros((8, 8)))
    from splatplan.render import MountedCamera

    with pytest.raises(SplatplanError, match="no link"):
        ImageCost(rend, MountedCamera("nope"), robot, enc, np.zeros((8, 8, 3)))


def test_tiny_reach_run(setup):
    from splatplan.tasks.reach import ReachConfig, run_reach

    robot, ts, cam, q0, rend, enc = setup
    goal = q0 + np.array([0.1, 0.05, 0.0, 0.1, 0.0, -0.05, 0.1])
    target = np.asarray(cam.render(rend, robot, goal[None], background=(0.5,) * 3).rgb[0])
    cfg = ReachConfig(mppi=MPPIConfig(n_samples=8, horizon=6, n_knots=4, dt=0.1, temperature=0.1, noise_sigma=0.25), plan_iters=3, image_size=24, n_views=2, n_splats=20_000)
    t_goal = robot.link_poses(goal)[robot.link_names.index(cfg.camera_link)]
    res = run_reach(robot, ts, target, config=cfg, q0=q0, encoder=enc, renderer=rend, goal_camera_pose=t_goal)
    assert res.trajectory.shape == (cfg.mppi.horizon + 1, 7)
    extra_starts = (cfg.plan_starts - 1) * min(cfg.plan_start_iters, cfg.plan_iters - 1) + cfg.plan_starts * cfg.plan_start_refine  # multi-start initial plan
    refinements = cfg.refine_plan_iters + (cfg.mppi.horizon - 1) * cfg.refine_iters  # goal-state refinement
    # the goal search: a second initial plan (here all but its last iteration are its starts'), the route's iterations when it routed
    search = min(cfg.plan_start_iters, cfg.plan_iters - 1) + extra_starts + cfg.refine_plan_iters + (cfg.route_iters if res.extra["route"] == "routed" else 0)
    assert res.extra["route"] in ("not asked", "searched plan free", "no route found", "route costs more", "routed")
    assert len(res.extra["goal_search_costs"]) == 2 and (res.extra["route"] == "not asked") == (not res.extra["kept_goal_search"])
    assert res.iterations == cfg.plan_iters + extra_starts + search + refinements + (cfg.mppi.horizon - 1) * cfg.iters_per_step
    assert res.final_image.shape == (24, 24, 3) and len(res.views) >= 1
    assert np.isfinite(res.translation_error_m) and np.isfinite(res.rotation_error_deg)
    assert res.clearance_source == "analytic" and np.isfinite(res.min_clearance_m)
    s = res.summary()
    assert s["mppi_iterations"] == res.iterations and s["encoder"].startswith("thumbnail")
    with pytest.raises(SplatplanError, match="RGB"):
        run_reach(robot, ts, np.zeros((4, 4)), config=cfg, q0=q0, encoder=enc, renderer=rend)


def test_multi_start_plan_and_elite(setup):
    from dataclasses import replace

    from splatplan.tasks.reach import ReachConfig, run_reach

    robot, ts, cam, q0, rend, enc = setup
    goal = q0 + np.array([0.1, 0.05, 0.0, 0.1, 0.0, -0.05, 0.1])
    target = np.asarray(cam.render(rend, robot, goal[None], background=(0.5,) * 3).rgb[0])
    cfg = ReachConfig(mppi=MPPIConfig(n_samples=8, horizon=5, n_knots=4, dt=0.1, temperature=0.1, noise_sigma=0.25), plan_iters=4, image_size=24, n_views=0, n_splats=20_000, plan_starts=3, plan_start_iters=2, plan_chunk=1,
                      goal_search=False)  # the plain multi-start's count (test_tiny_reach_run counts the goal search)
    res = run_reach(robot, ts, target, config=cfg, q0=q0, encoder=enc, renderer=rend)
    # every start runs plan_start_iters; the chosen one continues to plan_iters
    refinements = cfg.refine_plan_iters + (cfg.mppi.horizon - 1) * cfg.refine_iters
    assert res.iterations == cfg.plan_iters + (cfg.plan_starts - 1) * cfg.plan_start_iters + cfg.plan_starts * cfg.plan_start_refine + refinements + (cfg.mppi.horizon - 1) * cfg.iters_per_step
    assert len(res.extra["plan_start_costs"]) == cfg.plan_starts
    assert res.trajectory.shape == (cfg.mppi.horizon + 1, 7) and np.all(np.isfinite(res.trajectory))
    res2 = run_reach(robot, ts, target, config=replace(cfg, mppi=replace(cfg.mppi, elite=True)), q0=q0, encoder=enc, renderer=rend)
    assert res2.iterations == res.iterations and np.all(np.isfinite(res2.trajectory))


def test_reach_rejects_zero_plan_starts():
    from splatplan.tasks.reach import ReachConfig, run_reach

    with pytest.raises(SplatplanError, match="plan_starts"):
        run_reach("panda", "tabletop", np.zeros((8, 8, 3), np.float32), config=ReachConfig(plan_starts=0))


def test_goal_refiner_ill_conditioned_quadratic():
    """The refiner keeps the plan unless a sample beats it (monotone), and its covariance follows a
    narrow valley: on a 7-D quadratic with condition number 1e4 it gets 1e-3 of the start cost."""
    from splatplan.planners.goal_refiner import GoalRefiner

    rng = np.random.default_rng(3)
    rot = np.linalg.qr(rng.standard_normal((7, 7)))[0]
    scale = np.logspace(0, 4, 7)

    def f(x):  # (K, 7) -> (K,)
        return np.sum(scale * (x @ rot.T) ** 2, axis=-1)

    x = rot.T @ (0.05 / np.sqrt(scale)) * 10.0  # off the minimum along every axis
    f0 = prev = float(f(x[None])[0])
    ref = GoalRefiner(7, 32, 0.05, rng=np.random.default_rng(0))
    for _ in range(150):
        d = ref.sample()
        assert d.shape == (32, 7) and np.all(d[0] == 0.0)
        b = ref.update(d, f(x[None] + d))
        x = x + d[b]
        cur = float(f(x[None])[0])
        assert cur <= prev
        prev = cur
    assert prev < 1e-3 * f0
    assert abs(np.linalg.det(ref.cov) - 1.0) < 1e-6
    with pytest.raises(SplatplanError, match="GoalRefiner"):
        GoalRefiner(7, 1, 0.05)


def test_goals_do_not_depend_on_the_image_size(setup):
    """Views are judged at <= 64 px: the 224 px camera is checked through exactly the 64 px camera
    (at full size single edge pixels of a filled view fall under the alpha bar and no goal survived),
    so a 224 px run gets the 64 px goals."""
    from splatplan.planners.reach_goals import make_reach_goals
    from splatplan.render.cameras import wrist_camera

    robot, ts, _, q0, rend, _ = setup
    c64, c224 = wrist_camera(robot, image_size=64), wrist_camera(robot, image_size=224)
    s = c224.scaled(64)
    assert (s.width, s.height) == (64, 64) and s.link_name == c64.link_name
    np.testing.assert_allclose(s.K, c64.K, rtol=1e-12)
    np.testing.assert_array_equal(s.offset, c64.offset)
    assert c64.scaled(64) is c64
    kw = dict(n=2, q_start=q0, n_behind=1, n_candidates=256, seed=0, min_contrast=0.0)
    g64 = make_reach_goals(robot, ts, rend, c64, **kw)
    g224 = make_reach_goals(robot, ts, rend, c224, **kw)
    assert [g["name"] for g in g64] == [g["name"] for g in g224]
    for a, b in zip(g64, g224):
        np.testing.assert_array_equal(a["q"], b["q"])


def test_goals_include_behind_wall_ones_with_the_tight_panda(setup):
    """The study's meaning rests on goals with the camera behind the bin's front wall: with the
    built-in (tight) Panda, make_reach_goals returns n_behind of them, first, each reachable and
    collision-free by the same checks as the others, and the same goals for the same seed."""
    from splatplan.planners.reach_goals import BEHIND_WALL, make_reach_goals
    from splatplan.render.cameras import wrist_camera
    from splatplan.tasks._common import load_task_scene
    from splatplan.tasks.reach import ReachConfig

    robot, _, _, q0, _, _ = setup
    assert robot.n_ellipsoids > 11  # the tight model, not the coarse one-per-link one
    cfg = ReachConfig()  # the study's scene and camera (the views are judged at its 64 px)
    ts = load_task_scene("tabletop", n_sigma=cfg.n_sigma, n_splats=cfg.n_splats)
    cam = wrist_camera(robot, cfg.image_size, cfg.fov_deg, cfg.camera_link)
    kw = dict(n=3, q_start=q0, n_behind=2, n_candidates=256, seed=0)
    with SplatRenderer(ts.splats, "cpu") as rend:
        goals = make_reach_goals(robot, ts, rend, cam, **kw)
        again = make_reach_goals(robot, ts, rend, cam, **kw)
    assert len(goals) == 3
    assert [g["behind_wall"] for g in goals] == [True, True, False]
    lo, hi = BEHIND_WALL
    for g in goals[:2]:
        p = g["camera_pose"][:3, 3]
        assert np.all(p > lo) and np.all(p < hi) and g["name"].endswith("_behind_wall")
        q = g["q"][None]
        c, qu, ax = robot.ellipsoids(q)
        assert ts.analytic.ellipsoid_clearance(c, qu, ax).min() > 0.02
        assert not np.asarray(ts.checker.collides_robot(robot, q)).any()
        assert not np.asarray(robot.self_collision(q)).any()
    for a, b in zip(goals, again):
        np.testing.assert_array_equal(a["q"], b["q"])
    # the goals are picked from reach_candidates' survivors: the same sampler, every filter's verdict kept
    from splatplan.planners.reach_goals import reach_candidates

    with SplatRenderer(ts.splats, "cpu") as rend:
        cands = reach_candidates(robot, ts, rend, cam, q_start=q0, n_candidates=256, seed=0)
    kept = cands.q[cands.kept]
    assert all(any(np.array_equal(g["q"], k) for k in kept) for g in goals)
    assert cands.counts()[-1][2] == int((cands.kept & cands.behind_wall).sum()) >= 2


def test_study_names_a_goal_shortfall(tmp_path, monkeypatch):
    import splatplan.planners.reach_goals as reach_goals
    import splatplan.tasks.reach as reach
    from splatplan.eval.reach import ReachStudyConfig, run

    monkeypatch.setattr(reach_goals, "make_reach_goals", lambda *a, **k: [])
    with pytest.raises(SplatplanError, match="found only 0 of 3 goal configurations"):
        run(ReachStudyConfig(n_goals=3, task=reach.ReachConfig(n_splats=20_000, image_size=16), device="cpu"))


def test_line_of_sight_uses_the_exact_scene_only():
    """The hidden-goal rule: the straight segment between the two cameras against the exact boxes,
    end points excluded; a 2 cm wall between them hides the goal, a segment over it does not."""
    from splatplan.planners.reach_goals import line_of_sight_m
    from splatplan.scenes.builtin.primitives import AnalyticScene, make_box

    wall = AnalyticScene(make_box((0.44, 0.0, 0.03), (0.01, 0.3, 0.12))[None], labels=["wall_front"])
    start = np.array([0.30, 0.0, 0.10])
    ends = np.array([[0.60, 0.0, 0.05], [0.60, 0.0, 0.40], [0.30, 0.0, -0.05], [0.60, 1.0, 0.05]])
    los = line_of_sight_m(wall, start, ends)
    assert los.shape == (4,)
    assert los[0] < 0  # through the wall
    assert los[1] > 0 and los[2] > 0 and los[3] > 0  # over it, beside it, not crossing it
    np.testing.assert_allclose(los[2], 0.44 - 0.01 - 0.30, atol=1e-9)  # the nearest point is the segment's start side
    assert line_of_sight_m(wall, start, np.zeros((0, 3))).shape == (0,)


@pytest.mark.slow
def test_hidden_goals_come_first_and_do_not_depend_on_the_robot_model():
    """With the studies' sampler, the goals are first those hidden from the start camera by the exact
    scene (their straight camera path runs through the bin's front wall), from either start view,
    the most textured view first; the line of sight of a candidate is the same for the tight and the
    coarse Panda (cameras and exact scene only). With the default sampler's shorter camera moves,
    nothing is hidden from the start above the bin (and nothing is called hidden)."""
    from splatplan.planners.reach_goals import HIDDEN_GOAL_SAMPLER, line_of_sight_m, make_reach_goals, reach_candidates, reach_start
    from splatplan.render.cameras import wrist_camera
    from splatplan.tasks._common import load_task_scene
    from splatplan.tasks.reach import ReachConfig

    cfg = ReachConfig()
    ts = load_task_scene("tabletop", n_sigma=cfg.n_sigma, n_splats=cfg.n_splats)
    tight, coarse = robots.load_robot("panda"), robots.load_robot("panda", model="coarse")
    cam = wrist_camera(tight, cfg.image_size, cfg.fov_deg, cfg.camera_link)
    li = tight.link_names.index(cfg.camera_link)
    with SplatRenderer(ts.splats, "cpu") as rend:
        for view in ("before_wall", "above_bin"):
            q0 = reach_start(tight, view=view)
            assert np.array_equal(q0, reach_start(coarse, view=view))
            kw = dict(q_start=q0, seed=0, **HIDDEN_GOAL_SAMPLER)
            ct = reach_candidates(tight, ts, rend, cam, **kw)
            cc = reach_candidates(coarse, ts, rend, wrist_camera(coarse, cfg.image_size, cfg.fov_deg, cfg.camera_link), **kw)
            goals = make_reach_goals(tight, ts, rend, cam, n=3, **kw)
            np.testing.assert_array_equal(ct.line_of_sight_m, cc.line_of_sight_m)
            assert ct.counts()[-1][3] == int((ct.kept & ct.occluded).sum()) >= 2, view
            n_hidden = min(3, int((ct.kept & ct.occluded).sum()))
            assert [g["occluded"] for g in goals] == [True] * n_hidden + [False] * (3 - n_hidden), view
            stds = [float(ct.view_std[np.flatnonzero([np.array_equal(g["q"], q) for q in ct.q])[0]]) for g in goals[:n_hidden]]
            assert stds == sorted(stds, reverse=True), view  # the most textured hidden view first
            p_start = (tight.link_poses(q0)[li] @ cam.offset)[:3, 3]
            for g in goals[:n_hidden]:
                p = g["camera_pose"][:3, 3]
                s = np.linspace(0, 1, 1001)[1:-1, None]
                assert ts.analytic.sdf(p_start * (1 - s) + p * s).min() < 0  # independently: the segment enters the geometry
                assert g["line_of_sight_m"] == pytest.approx(float(line_of_sight_m(ts.analytic, p_start, p[None])[0]))
                assert ts.analytic.sdf(p[None])[0] > 0  # the goal camera itself is in free space
        above = make_reach_goals(tight, ts, rend, cam, n=2, q_start=reach_start(tight), n_candidates=256, seed=0)
    assert not any(g["occluded"] for g in above) and all(g["line_of_sight_m"] > 0 for g in above)


def test_view_contrast_is_spatial():
    """A view of one flat colour has no contrast whatever the colour (a flat red once counted, the
    std of the flattened pixels and channels); texture in any channel counts."""
    from splatplan.planners.reach_goals import view_contrast

    flat = np.broadcast_to(np.array([0.9, 0.1, 0.1]), (2, 64, 3))
    np.testing.assert_allclose(view_contrast(flat), 0.0, atol=1e-12)
    assert float(np.asarray(flat).reshape(2, -1).std(axis=1)[0]) > 0.3  # (what the flattened std said)
    checker = np.zeros((1, 64, 3))
    checker[0, ::2] = 1.0
    np.testing.assert_allclose(view_contrast(checker), [0.5])
    green = np.zeros((1, 64, 3))
    green[0, ::2, 1] = 1.0
    np.testing.assert_allclose(view_contrast(green), [0.5 / 3])
