"""checker.query_robot / collides_robot: FK on the device -> metric, against the explicit path
``query(*robot.ellipsoids(q))`` and the float64 reference; numpy, torch and wp joint inputs."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan._warp import wp as _wp
from splatplan.errors import SplatplanError
from splatplan.metric import CollisionChecker, MetricConfig
from splatplan.robots import load_robot
from splatplan.scenes.splats import Splats, quat_to_rotmat, rotmat_to_quat

from .conftest import DEVICES, random_quats, random_scene
from .test_kernel_vs_reference import _check_against_reference

wp = _wp()
FIELDS = ("min_s2", "n_colliding", "in_collision", "softmin", "cost")


@wp.kernel
def _translate_fk(q: wp.array2d(dtype=wp.float32), offs: wp.array(dtype=wp.vec3), rots: wp.array(dtype=wp.mat33),
                  n_e: int, out_c: wp.array(dtype=wp.vec3), out_r: wp.array(dtype=wp.mat33)):  # fmt: skip
    b, e = wp.tid()
    out_c[b * n_e + e] = wp.vec3(q[b, 0], q[b, 1], q[b, 2]) + offs[e]
    out_r[b * n_e + e] = rots[e]


class TranslatingRobot:
    """A stand-in for splatplan.robots.Robot: 3 ellipsoids at fixed offsets/orientations moved by q = (x, y, z)."""

    name = "translating"
    dof = 3
    n_ellipsoids = 3

    def __init__(self, seed: int = 0):
        rng = np.random.default_rng(seed)
        self.offsets = rng.uniform(-0.03, 0.03, (3, 3))
        self.rots = quat_to_rotmat(random_quats(rng, 3))  # (E, 3, 3) world <- ellipsoid
        self.semi_axes = np.array([[0.02, 0.01, 0.015], [0.015, 0.015, 0.015], [0.03, 0.01, 0.01]])

    def check_q(self, q, **_):
        a = np.array(q, dtype=np.float64)
        if a.ndim == 0 or a.shape[-1] != 3:
            raise SplatplanError(f"robot {self.name}: configurations need 3 values, got shape {a.shape}")
        if not np.isfinite(a).all():
            raise SplatplanError(f"robot {self.name}: a configuration contains NaN or Inf")
        return a

    def ellipsoids(self, q):
        q = self.check_q(q)
        c = q[..., None, :] + self.offsets  # (..., E, 3)
        quats = np.broadcast_to(rotmat_to_quat(self.rots), c.shape[:-1] + (4,))
        return c, quats, self.semi_axes.copy()

    def fk_wp(self, q_wp, out_centers, out_rots):
        dev = q_wp.device
        offs = wp.array(self.offsets.astype(np.float32), dtype=wp.vec3, device=dev)
        rots = wp.array(self.rots.astype(np.float32), dtype=wp.mat33, device=dev)
        wp.launch(_translate_fk, dim=(q_wp.shape[0], 3), inputs=[q_wp, offs, rots, 3, out_centers, out_rots], device=dev)


def _check_robot(scene, robot, q, cfg, res, hit):
    """query_robot's outputs against the float64 brute force on robot.ellipsoids(q)."""
    c, quats, ax = robot.ellipsoids(q)
    e = robot.n_ellipsoids
    assert res.min_s2.shape == q.shape[:-1] + (e,) and hit.shape == q.shape[:-1] + (e,)
    flat = lambda x: np.asarray(x).reshape(-1)  # noqa: E731
    got = type("R", (), {k: flat(getattr(res, k)) for k in FIELDS})
    n = c.reshape(-1, 3).shape[0]
    _check_against_reference(scene, c.reshape(-1, 3), quats.reshape(-1, 4), np.tile(ax, (n // e, 1)), cfg, got, flat(hit))


@pytest.mark.parametrize("device", DEVICES)
def test_query_robot_matches_reference(device):
    rng = np.random.default_rng(0)
    scene = random_scene(rng, 1000)
    robot = TranslatingRobot()
    q = (scene.means[rng.integers(0, len(scene), 40)] + rng.normal(0, 0.02, (40, 3))).reshape(8, 5, 3)  # (K, T, dof)
    cfg = MetricConfig(n_sigma=1.0)
    ch = CollisionChecker(scene, config=cfg, device=device)
    res, hit = ch.query_robot(robot, q), ch.collides_robot(robot, q)
    _check_robot(scene, robot, q, cfg, res, hit)
    explicit = ch.query(*robot.ellipsoids(q))
    np.testing.assert_allclose(res.min_s2, explicit.min_s2, rtol=1e-4, atol=1e-5)
    # wp and torch joint inputs give the same results on their own type
    qw = ch.query_robot(robot, wp.array(q.astype(np.float32), device=device))
    assert isinstance(qw.min_s2, wp.array) and qw.min_s2.shape == (8, 5, 3)
    np.testing.assert_array_equal(qw.n_colliding.numpy(), res.n_colliding)
    torch = pytest.importorskip("torch")
    if device == "cpu" or torch.cuda.is_available():
        qt = torch.tensor(q, device="cpu" if device == "cpu" else device)
        rt = ch.query_robot(robot, qt)
        assert isinstance(rt.min_s2, torch.Tensor) and rt.min_s2.shape == (8, 5, 3)
        np.testing.assert_allclose(rt.min_s2.cpu().numpy(), res.min_s2, rtol=1e-6)
        np.testing.assert_array_equal(ch.collides_robot(robot, qt).cpu().numpy(), hit)


@pytest.mark.parametrize("device", DEVICES)
def test_query_robot_workspace_and_bad_q(device):
    rng = np.random.default_rng(1)
    scene = random_scene(rng, 600)
    robot = TranslatingRobot(1)
    ch = CollisionChecker(scene, n_sigma=1.0, device=device)
    ws = ch.workspace()
    q = scene.means[:50].astype(np.float32)
    qw = wp.array(q, device=device)
    first = ch.query_robot(robot, qw, out=ws).min_s2.numpy().copy()
    ptr, n_alloc = ws.min_s2.ptr, ws.reallocations
    again = ch.query_robot(robot, qw, out=ws)
    assert again.min_s2.ptr == ptr and ws.reallocations == n_alloc
    np.testing.assert_array_equal(again.min_s2.numpy(), first)
    q[3, 1] = np.nan
    bad = ch.collides_robot(robot, wp.array(q, device=device))
    assert bad.numpy()[3].all()  # a NaN configuration is never free
    with pytest.raises(SplatplanError, match="invalid"):
        ch.query_robot(robot, wp.array(q, device=device), validate=True)
    with pytest.raises(SplatplanError, match="NaN"):
        ch.query_robot(robot, q)
    with pytest.raises(SplatplanError, match="shape"):
        ch.query_robot(robot, wp.array(np.zeros((4, 2), np.float32), device=device))
    assert ch.query_robot(robot, np.zeros((0, 3))).min_s2.shape == (0, 3)
    assert ch.collides_robot(robot, np.zeros(3)).shape == (3,)  # one configuration -> (E,)


def _arm_scene(rng, n=3000) -> Splats:
    """Splats around a Panda's workspace (metres, z up)."""
    s = random_scene(rng, n, scale=0.01)
    means = rng.uniform([-0.7, -0.7, 0.0], [0.7, 0.7, 1.1], (n, 3))
    return Splats(means, s.quats, s.scales, s.opacities, s.colors)


@pytest.mark.parametrize("device", DEVICES)
def test_panda_query_robot_matches_explicit_path(device):
    robot = load_robot("panda")
    rng = np.random.default_rng(2)
    scene = _arm_scene(rng)
    lo, hi = robot.joint_limits[:, 0], robot.joint_limits[:, 1]
    q = rng.uniform(lo, hi, (6, 4, robot.dof))  # (K, T, dof)
    cfg = MetricConfig(n_sigma=1.0)
    ch = CollisionChecker(scene, config=cfg, device=device)
    res, hit = ch.query_robot(robot, q), ch.collides_robot(robot, q)
    assert res.min_s2.shape == (6, 4, robot.n_ellipsoids)
    explicit = ch.query(*robot.ellipsoids(q))
    m = explicit.min_s2 < cfg.s2_cap
    np.testing.assert_allclose(res.min_s2[m], explicit.min_s2[m], rtol=1e-3, atol=1e-4)
    assert res.in_collision.any() and (~res.in_collision).any()
    _check_robot(scene, robot, q, cfg, res, hit)
    qw = wp.array(q.astype(np.float32), device=device)
    np.testing.assert_array_equal(ch.collides_robot(robot, qw).numpy(), hit)


@pytest.mark.parametrize("device", DEVICES + ["reference"])
def test_query_robot_on_an_ellipsoid_subset(device):
    """ellipsoids=[...]: those columns of the full query, in the given order; bad lists are named.
    Counts and flags are exact; float sums to rounding (the subset's semi-axes size the grid
    tiers, so cells are visited in another order)."""
    robot = load_robot("panda")
    rng = np.random.default_rng(5)
    scene = _arm_scene(rng)
    q = rng.uniform(robot.joint_limits[:, 0], robot.joint_limits[:, 1], (5, 3, robot.dof))
    backend = {"backend": "reference"} if device == "reference" else {"device": device}
    ch = CollisionChecker(scene, n_sigma=1.0, **backend)
    full, hit = ch.query_robot(robot, q), ch.collides_robot(robot, q)
    sub = [9, 1, 4, 10]
    part = ch.query_robot(robot, q, ellipsoids=sub)
    assert part.min_s2.shape == (5, 3, len(sub))
    for f in ("n_colliding", "in_collision"):
        np.testing.assert_array_equal(getattr(part, f), getattr(full, f)[..., sub], err_msg=f)
    for f in ("min_s2", "softmin", "cost"):
        np.testing.assert_allclose(getattr(part, f), getattr(full, f)[..., sub], rtol=1e-5, atol=1e-7, err_msg=f)
    np.testing.assert_array_equal(ch.collides_robot(robot, q, ellipsoids=sub), hit[..., sub])
    for bad in ([], [robot.n_ellipsoids], [-1]):
        with pytest.raises(SplatplanError, match="ellipsoids must be"):
            ch.query_robot(robot, q, ellipsoids=bad)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("n_sigma", [0.0, 1.0])
def test_collides_robot_fast_paths_match_reference(device, n_sigma):
    """The collision-only kernel's row clipping and the unsorted robot batch (TierConfig
    collide_row_clip, sort_robot_collides, both on and off) against the float64 brute force, on a
    batch large enough to be sorted (> sort_min_batch queries)."""
    from splatplan.metric.wp_metric import TierConfig

    # the coarse model (11 ellipsoids): the tight default's thinnest ellipsoids (6 mm semi-axes) put
    # 2 of 7,509 min_s2 values 4e-4 (relative) off the float64 reference, beyond this test's float32
    # tolerance of 1e-4
    robot = load_robot("panda", model="coarse")
    rng = np.random.default_rng(11)
    scene = _arm_scene(rng)
    q = rng.uniform(robot.joint_limits[:, 0], robot.joint_limits[:, 1], (160, robot.dof))  # 1,760 ellipsoids
    cfg = MetricConfig(n_sigma=n_sigma)
    hits = []
    for clip, sort in ((True, False), (False, False), (True, True), (False, True)):
        ch = CollisionChecker(scene, config=cfg, device=device, tiers=TierConfig(collide_row_clip=clip, sort_robot_collides=sort, cell_factor=0.5))
        hits.append(np.asarray(ch.collides_robot(robot, q)))
    for h in hits[1:]:
        np.testing.assert_array_equal(h, hits[0])
    res = CollisionChecker(scene, config=cfg, device=device).query_robot(robot, q)
    _check_robot(scene, robot, q, cfg, res, hits[0])
    assert hits[0].any() and (~hits[0]).any()
