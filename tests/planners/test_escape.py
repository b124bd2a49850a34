"""Endpoint escapes (splatplan.planners.escape): an endpoint the margin blocks is left by a segment
checked finer with a smaller margin, and the margin's guarantee still holds along the whole path.

The guarantee, checked here by brute force against the splat means (n_sigma 0: a grown sphere
collides iff a mean lies inside it): every configuration of the returned path, sampled far finer
than any check, keeps the sphere's centre at least R + rho from every mean (rho = the margin's
covering estimate, margin - r / 2), the clearance the planner's own edges keep.
"""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import PlanningError, SplatplanError
from splatplan.planners import RRTConfig, escape_endpoint, plan
from splatplan.planners.escape import MAX_ESCAPE_N_SIGMA, endpoint_check, escape_n_sigmas, push_directions
from splatplan.planners.robot_links import LinkGeometry
from splatplan.robots import load_robot
from splatplan.scenes.builtin.ellipsoid_clearance import project_to_ellipsoid
from splatplan.scenes.margin import SplatMargin, margin_for
from splatplan.scenes.splats import Splats, quat_to_rotmat

from .scenes import make_checker, wall_scene

R = 0.015
#: margin m = rho + r / 2 with rho = 16 mm, r = 8 mm
MARGIN = SplatMargin(margin=0.020, spacing=0.004, edge_resolution=0.008, n_sigma=0.0)
RHO = MARGIN.covering_estimate


@pytest.fixture(scope="module")
def setup():
    splats = wall_scene()
    return splats, make_checker(splats, n_sigma=0.0), load_robot(f"sphere:{R}")


def _min_dist(means: np.ndarray, path: np.ndarray, step: float = 2e-4) -> float:
    """Smallest distance from the path (P, 3), sampled every ``step``, to any mean."""
    pts = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        pts.append(a + (np.arange(1, n + 1) / n)[:, None] * (b - a))
    p = np.concatenate(pts)
    d = np.inf
    for chunk in np.array_split(p, max(1, len(p) // 512)):
        d = min(d, float(np.sqrt(((chunk[:, None, :] - means[None]) ** 2).sum(-1)).min()))
    return d


def _at_distance(splats, d: float, side: float = -1.0) -> np.ndarray:
    """The point (x, 0, 0.06) on the ``side`` of the wall whose nearest mean is ``d`` away (bisection)."""
    means = np.asarray(splats.means, dtype=np.float64)
    near, far = 0.0, 0.2
    for _ in range(60):
        mid = 0.5 * (near + far)
        if _min_dist(means, np.array([[side * mid, 0.0, 0.06]])) < d:
            near = mid
        else:
            far = mid
    return np.array([side * far, 0.0, 0.06])


def test_free_endpoint_needs_no_escape(setup):
    splats, checker, robot = setup
    q = np.array([-0.2, 0.0, 0.06])
    esc = escape_endpoint(checker, robot, q, MARGIN)
    assert not esc.escaped and esc.divisor == 1 and esc.path.shape == (1, 3)
    np.testing.assert_array_equal(esc.path[0], q)


def test_blocked_endpoint_escapes_with_the_guarantee(setup):
    splats, checker, robot = setup
    q = _at_distance(splats, R + 0.019)  # 19 mm from the wall: inside the 20 mm margin, outside rho + r/32
    means = np.asarray(splats.means)
    assert R + MARGIN.margin > _min_dist(means, q[None]) > R + RHO + MARGIN.edge_resolution / 32
    esc = escape_endpoint(checker, robot, q, MARGIN, toward=np.array([0.2, 0.0, 0.06]))
    assert esc.escaped and esc.divisor in (2, 4, 8, 16)
    np.testing.assert_array_equal(esc.path[0], q)
    # the escape configuration is free for the full margin (a valid start for the planner)
    assert _min_dist(means, esc.path[-1:]) >= R + MARGIN.margin - 1e-5
    # the segment keeps R + rho, and the margin it was checked with is rho + r / (2 f)
    assert _min_dist(means, esc.path) >= R + RHO - 1e-5
    assert esc.margin == pytest.approx(RHO + MARGIN.edge_resolution / (2 * esc.divisor))
    assert esc.resolution == pytest.approx(MARGIN.edge_resolution / esc.divisor)
    assert esc.n_configs > 1 and 0 < esc.displacement <= 4 * MARGIN.margin + 1e-9


def test_endpoint_closer_than_the_finest_check_is_refused(setup):
    splats, checker, robot = setup
    q = _at_distance(splats, R + 0.012)  # 12 mm: inside rho (16 mm)
    with pytest.raises(PlanningError, match="finest endpoint check"):
        escape_endpoint(checker, robot, q, MARGIN)


def test_plan_with_margin_escapes_both_ends_and_keeps_the_guarantee(setup):
    splats, checker, robot = setup
    start, goal = _at_distance(splats, R + 0.019), _at_distance(splats, R + 0.0185, side=1.0)
    box = RRTConfig(time_limit_s=20.0, box_lo=(-0.2, -0.3, 0.0), box_hi=(0.2, 0.3, 0.2))
    res = plan(checker, start, goal, robot=robot, margin=MARGIN, refine=False, seed=3, rrt_config=box)
    assert res.success, res.message
    np.testing.assert_array_equal(res.path[0], start)
    np.testing.assert_array_equal(res.path[-1], goal)
    esc = res.info["escape"]
    assert esc["start"]["escaped"] and esc["goal"]["escaped"]
    assert res.info["time_split"]["escape"] >= 0 and res.n_configs >= esc["start"]["n_configs"] + esc["goal"]["n_configs"]
    assert _min_dist(np.asarray(splats.means), res.path) >= R + RHO - 1e-5


def test_plan_with_margin_free_endpoints_is_the_grown_robot_plan(setup):
    splats, checker, robot = setup
    start, goal = np.array([-0.2, 0.0, 0.06]), np.array([0.2, 0.0, 0.06])
    box = {"box_lo": (-0.25, -0.3, 0.0), "box_hi": (0.25, 0.3, 0.2)}
    a = plan(checker, start, goal, robot=robot, margin=MARGIN, refine=False, seed=1, rrt_config=RRTConfig(**box))
    b = plan(checker, start, goal, robot=robot.inflated(MARGIN.margin), refine=False, seed=1, rrt_config=RRTConfig(edge_resolution=MARGIN.edge_resolution, **box))
    assert a.success and b.success
    np.testing.assert_allclose(a.path, b.path)
    assert not a.info["escape"]["start"]["escaped"] and not a.info["escape"]["goal"]["escaped"]


def test_plan_margin_bad_requests(setup):
    _, checker, robot = setup
    s, g = np.array([-0.2, 0.0, 0.06]), np.array([0.2, 0.0, 0.06])
    with pytest.raises(SplatplanError, match="coarser"):
        plan(checker, s, g, robot=robot, margin=MARGIN, rrt_config=RRTConfig(edge_resolution=0.02))
    with pytest.raises(SplatplanError, match="SplatMargin"):
        plan(checker, s, g, robot=robot, margin=0.02)  # type: ignore[arg-type]
    with pytest.raises(SplatplanError, match="OMPL"):
        plan(checker, s, g, robot=robot, margin=MARGIN, planner="ompl:RRTConnect")
    with pytest.raises(SplatplanError, match="finite"):
        escape_endpoint(checker, robot, np.array([np.nan, 0.0, 0.0]), MARGIN)
    with pytest.raises(SplatplanError, match="divisors"):
        escape_endpoint(checker, robot, s, MARGIN, fine=(1,))


def test_escape_robot_checks_the_segment_with_the_tighter_model(setup):
    """A tighter model (here a smaller sphere) frees an endpoint the planning model cannot leave even
    at the finest divisor; the segment then keeps R_tight + rho, the escape point the full margin."""
    splats, checker, robot = setup
    r_tight = 0.011
    tight = load_robot(f"sphere:{r_tight}")
    q = _at_distance(splats, R + 0.013)  # the planning sphere: 13 mm (< rho: refused); the tight one 17 mm
    with pytest.raises(PlanningError, match="finest"):
        escape_endpoint(checker, robot, q, MARGIN)
    esc = escape_endpoint(checker, robot, q, MARGIN, escape_robot=tight, toward=np.array([-0.2, 0.0, 0.06]))
    assert esc.escaped
    means = np.asarray(splats.means)
    assert _min_dist(means, esc.path) >= r_tight + RHO - 1e-5
    assert _min_dist(means, esc.path[-1:]) >= R + MARGIN.margin - 1e-5
    with pytest.raises(SplatplanError, match="degrees of freedom"):
        escape_endpoint(checker, robot, q, MARGIN, escape_robot=load_robot("panda"))


def _min_dist_ellipsoids(splats, path: np.ndarray, n_sigma: float, step: float = 5e-4) -> float:
    """Smallest distance from the path (P, 3), sampled every ``step``, to any splat's n-sigma ellipsoid."""
    pts = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        pts.append(a + (np.arange(1, n + 1) / n)[:, None] * (b - a))
    p = np.concatenate(pts)  # (P, 3)
    mu = np.asarray(splats.means, dtype=np.float64)
    rot = quat_to_rotmat(np.asarray(splats.quats, dtype=np.float64)).reshape(-1, 3, 3)  # world <- splat
    semi = n_sigma * np.asarray(splats.scales, dtype=np.float64)  # (N, 3)
    best = np.inf
    for x in p:
        u = np.einsum("nji,nj->ni", rot, x - mu)  # (N, 3) in each splat's frame
        best = min(best, float(np.linalg.norm(u - project_to_ellipsoid(u, semi), axis=1).min()))
    return best


def test_a_higher_n_sigma_frees_what_the_means_cannot_with_the_guarantee(setup):
    """An endpoint closer to the wall than rho(0) plus the finest r / 32 (refused at the planner's
    n_sigma 0) is left by a segment checked at the margin's floor n_sigma with rho(n), the smaller
    covering radius of the splats' n-sigma ellipsoids; the segment keeps R + rho(n) from every one
    of them (brute force over the whole segment), the escape point is free for the full margin."""
    splats, checker, robot = setup
    margin = margin_for(splats, robot, 0.0)  # derived: rho(0) = 3 h, s_t known
    n_e = min(margin.floor_n_sigma, 3.0)
    rho_e = margin.covering_at(n_e)
    assert rho_e < margin.covering_estimate - 0.005
    d = R + 0.5 * (rho_e + margin.covering_estimate)  # between rho(n_e) and rho(0)
    q = _at_distance(splats, d)
    with pytest.raises(PlanningError, match="n_sigma tried: 0"):
        escape_endpoint(checker, robot, q, margin, n_sigmas=())
    esc = escape_endpoint(checker, robot, q, margin, toward=np.array([-0.25, 0.0, 0.06]))
    assert esc.escaped and esc.n_sigma == pytest.approx(n_e)
    assert esc.margin == pytest.approx(rho_e + margin.edge_resolution / (2 * esc.divisor))
    means = np.asarray(splats.means)
    assert _min_dist(means, esc.path[-1:]) >= R + margin.margin - 1e-5  # the full margin at n_sigma 0 frees the escape point
    assert _min_dist_ellipsoids(splats, esc.path, n_e) >= R + rho_e - 1e-5
    # the planner's own n_sigma first: an endpoint it frees at some divisor escapes at n_sigma 0
    q2 = _at_distance(splats, R + margin.covering_estimate + 0.6 * margin.edge_resolution / 2)
    esc2 = escape_endpoint(checker, robot, q2, margin, toward=np.array([-0.25, 0.0, 0.06]))
    assert esc2.escaped and esc2.n_sigma == 0.0
    # the planner reports the n_sigma of each escape
    box = RRTConfig(time_limit_s=20.0, box_lo=(-0.25, -0.3, 0.0), box_hi=(0.25, 0.3, 0.2))
    res = plan(checker, q, np.array([-0.2, 0.1, 0.06]), robot=robot, margin=margin, refine=False, seed=2, rrt_config=box)
    assert res.success and res.info["escape"]["start"]["n_sigma"] == pytest.approx(n_e) and res.info["escape"]["goal"]["n_sigma"] == 0.0


def test_the_default_escape_n_sigmas_go_down_from_the_floor():
    """The floor n_sigma first (all a higher n_sigma can save), then the whole numbers below it,
    highest first (an edge's splats reach past it less at a lower n_sigma); none without s_t."""
    m = SplatMargin(margin=0.01, spacing=0.002, edge_resolution=0.004, n_sigma=0.0, tangential_std=0.0017)
    floor = m.floor_n_sigma
    assert floor == pytest.approx(2.5 * 0.002 / 0.0017) and 2 < floor < 3
    assert escape_n_sigmas(m, 0.0) == pytest.approx((floor, 2.0, 1.0))
    assert escape_n_sigmas(m, 1.0) == pytest.approx((floor, 2.0))
    wide = SplatMargin(margin=0.01, spacing=0.002, edge_resolution=0.004, n_sigma=0.0, tangential_std=0.0005)  # floor at n = 10
    assert escape_n_sigmas(wide, 0.0) == (MAX_ESCAPE_N_SIGMA, 2.0, 1.0)
    assert escape_n_sigmas(MARGIN, 0.0) == ()


def test_an_explicit_n_sigma_order_is_followed(setup):
    """endpoint_check tries the planner's own n_sigma, then the given ones in the given order."""
    splats, checker, robot = setup
    margin = margin_for(splats, robot, 0.0)
    q = _at_distance(splats, R + 0.5 * (margin.covering_at(3.0) + margin.covering_estimate))
    assert endpoint_check(checker, robot, q, margin, n_sigmas=()) is None
    for order in ((3.0, 2.0), (2.0, 3.0)):
        n, f = endpoint_check(checker, robot, q, margin, n_sigmas=order)
        assert n in order and (n == order[0] or endpoint_check(checker, robot, q, margin, n_sigmas=order[:1]) is None)


def test_push_direction_leads_away_from_the_splats(setup):
    """The push of a sphere blocked beside the wall points away from the wall (the mean of the
    splats inside its grown bounding sphere lies on the wall)."""
    splats, checker, robot = setup
    q = _at_distance(splats, R + 0.019)  # on the x < 0 side of the wall
    full = LinkGeometry(robot.inflated(MARGIN.margin))
    d = push_directions(checker, full, q)
    assert d.shape == (1, 3)
    u = d[0] / np.linalg.norm(d[0])
    assert u[0] < -0.9  # away from the wall (x = 0)
    free = np.array([-0.2, 0.0, 0.06])  # nothing blocks a free configuration
    assert push_directions(checker, full, free).shape == (0, 3)


def test_push_directions_of_an_arm_move_the_blocked_ellipsoids_out():
    """Panda above a table of splats 3 mm below its hand (free for its own model, blocked for the model
    grown by 1 cm): every push direction moves the centres of the blocked ellipsoids away from the
    table (checked by FK, not by the Jacobian used to find it), and a short step along each frees
    the grown arm."""
    robot = load_robot("panda")
    q = np.asarray(robot.q_default, dtype=np.float64)
    c, quat, ax = robot.ellipsoids(q[None])
    c, rot, ax = np.asarray(c[0], dtype=np.float64), quat_to_rotmat(np.asarray(quat[0])), np.asarray(ax, dtype=np.float64)
    hand = int(np.argmax(np.linalg.norm(c[:, :2], axis=1)))  # the ellipsoid farthest from the base's axis (the hand's)
    reach_z = np.sqrt(np.einsum("ej,ej->e", rot[:, 2, :] ** 2, ax**2))  # (E,) each ellipsoid's extent along z
    near = np.linalg.norm(c[:, :2] - c[hand, :2], axis=1) < 0.06
    z0 = float((c[near, 2] - reach_z[near]).min()) - 0.003
    rng = np.random.default_rng(0)
    table = np.array([c[hand, 0], c[hand, 1], z0]) + rng.uniform(-0.06, 0.06, (1600, 3)) * np.array([1.0, 1.0, 0.0])
    n = len(table)
    splats = Splats(table, np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), np.full((n, 3), 1e-3), np.full(n, 0.9), np.full((n, 3), 0.5))
    checker = make_checker(splats, n_sigma=0.0)
    full = LinkGeometry(robot.inflated(0.01))
    hit = np.asarray(checker.collides_robot(full.robot, q[None]))[0]
    assert hit.any() and not checker.collides_configs(robot, q[None])[0]
    dirs = push_directions(checker, full, q)
    assert len(dirs) >= 1
    for d in dirs:
        d = d / full.motion(d[None])[0]  # a unit step moves no point of the arm farther than 1 m
        c1 = np.asarray(robot.ellipsoids((q + 0.005 * d)[None])[0][0], dtype=np.float64)
        assert np.all(c1[hit, 2] > c[hit, 2])  # up, away from the table
        freed = [t for t in np.linspace(0.002, 0.04, 20) if not checker.collides_configs(full.robot, (q + t * d)[None])[0]]
        assert freed, "no step of up to 4 cm along a push frees the grown arm"


def test_second_round_escapes_where_the_first_direction_fails(setup):
    """One direction in the first round, straight into the wall: the second round's push leaves it,
    with the guarantee."""
    splats, checker, robot = setup
    q = _at_distance(splats, R + 0.019)
    esc = escape_endpoint(checker, robot, q, MARGIN, toward=np.array([0.2, 0.0, 0.06]), n_directions=1)
    assert esc.escaped and esc.info["push_directions"] == 1 and esc.info["directions"] > 1
    means = np.asarray(splats.means)
    assert _min_dist(means, esc.path[-1:]) >= R + MARGIN.margin - 1e-5
    assert _min_dist(means, esc.path) >= R + RHO - 1e-5


def test_without_a_second_round_the_first_directions_decide(setup):
    splats, checker, robot = setup
    q = _at_distance(splats, R + 0.019)
    with pytest.raises(PlanningError, match="none of 1 straight segments"):
        escape_endpoint(checker, robot, q, MARGIN, toward=np.array([0.2, 0.0, 0.06]), n_directions=1, retry=0)
    with pytest.raises(SplatplanError, match="retry must be >= 0"):
        escape_endpoint(checker, robot, q, MARGIN, retry=-1)
