"""Forward kinematics: Warp kernel vs the numpy reference, numpy reference vs Pinocchio."""

from __future__ import annotations

import numpy as np
import pytest

from .conftest import devices, random_q


def _kernel_vs_reference(robot, q, device):
    c, r = robot.fk(q, device=device)  # Warp, float32
    c0, r0 = robot.ellipsoid_frames(q)  # numpy, float64
    np.testing.assert_allclose(c, c0, atol=2e-6)
    np.testing.assert_allclose(r, r0, atol=2e-6)
    # rotations stay rotations
    np.testing.assert_allclose(np.einsum("...ij,...kj->...ik", r, r), np.broadcast_to(np.eye(3), r.shape), atol=2e-6)


@pytest.mark.parametrize("device", devices())
@pytest.mark.parametrize("name", ["panda", "go2", "ellipsoid:0.1,0.05,0.02", "tree"])
def test_kernel_matches_reference(name, device, tree_robot):
    from splatplan.robots import load_robot

    robot = tree_robot if name == "tree" else load_robot(name)
    # 9000 configurations: split across the CPU thread pool in several launches
    q = random_q(robot, 9000, seed=1)
    _kernel_vs_reference(robot, q, device)


def test_kernel_batch_shapes_and_mimic(tree_robot):
    robot = tree_robot
    q = random_q(robot, 12, seed=2).reshape(3, 4, robot.dof)
    c, r = robot.fk(q)
    assert c.shape == (3, 4, robot.n_ellipsoids, 3) and r.shape == (3, 4, robot.n_ellipsoids, 3, 3)
    # the mimic joint j4 follows j1: l4's pose depends on j1 only through -0.5*j1 + 0.3
    poses = robot.link_poses(np.zeros(robot.dof))
    assert poses.shape == (len(robot.link_names), 4, 4)
    # the tree needs scratch slots (branching) and has a prismatic, a continuous and a mimic joint
    from splatplan.robots.wp_fk import model_arrays

    a = model_arrays(robot)
    assert (a["slot"] >= 0).sum() >= 2 and {1, 2}.issubset(set(a["jtype"].tolist()))


def test_fk_wp_stays_on_device_and_validates(panda):
    from splatplan._warp import wp as _wp
    from splatplan.errors import SplatplanError

    wp = _wp()
    q = random_q(panda, 64, seed=3).astype(np.float32)
    qw = wp.array(q, dtype=wp.float32, device="cpu")
    e = panda.n_ellipsoids
    oc = wp.zeros(64 * e, dtype=wp.vec3, device="cpu")
    orr = wp.zeros(64 * e, dtype=wp.mat33, device="cpu")
    panda.fk_wp(qw, oc, orr)
    c0, r0 = panda.ellipsoid_frames(q.astype(np.float64))
    np.testing.assert_allclose(oc.numpy().reshape(64, e, 3), c0, atol=2e-6)
    with pytest.raises(SplatplanError, match="shape"):
        panda.fk_wp(wp.array(q[:, :6].copy(), dtype=wp.float32, device="cpu"), oc, orr)
    with pytest.raises(SplatplanError, match="rows"):
        panda.fk_wp(qw, wp.zeros(10, dtype=wp.vec3, device="cpu"), orr)


# ------------------------------------------------------------------------------- Pinocchio


def _pin_q(model, values: dict[str, float]) -> np.ndarray:
    import pinocchio as pin

    q = pin.neutral(model)
    for jid in range(1, model.njoints):
        name, j = model.names[jid], model.joints[jid]
        v = values[name]
        if j.nq == 1:
            q[j.idx_q] = v
        elif j.nq == 2:  # continuous joint: (cos, sin)
            q[j.idx_q : j.idx_q + 2] = np.cos(v), np.sin(v)
        else:  # planar root: (x, y, cos, sin)
            q[j.idx_q : j.idx_q + 4] = v[0], v[1], np.cos(v[2]), np.sin(v[2])
    return q


def _compare_with_pin(robot, pin_model, values_fn, n=20, seed=4, lift=np.eye(4)):
    import pinocchio as pin

    data = pin_model.createData()
    for q in random_q(robot, n, seed=seed):
        ours = robot.link_poses(q)
        pin.framesForwardKinematics(pin_model, data, _pin_q(pin_model, values_fn(q)))
        for li, link in enumerate(robot.link_names):
            fid = pin_model.getFrameId(link)
            theirs = lift @ data.oMf[fid].homogeneous
            np.testing.assert_allclose(ours[li], theirs, atol=1e-5, err_msg=link)


def test_panda_matches_pinocchio(panda):
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(panda.info["urdf"])
    finger = 0.001  # the SRDF "default" opening our built-in is fixed at

    def values(q):
        return {**dict(zip(panda.joint_names, q)), "panda_finger_joint1": finger, "panda_finger_joint2": finger}

    _compare_with_pin(panda, model, values)


def test_go2_planar_matches_pinocchio(go2):
    pin = pytest.importorskip("pinocchio")
    from splatplan.robots.urdf import read_srdf

    model = pin.buildModelFromUrdf(go2.info["urdf"], pin.JointModelPlanar())
    standing = read_srdf(go2.info["srdf"]).group_states["standing"]

    def values(q):
        v = {k: vals[0] for k, vals in standing.items() if len(vals) == 1}
        v["root_joint"] = q
        return v

    _compare_with_pin(go2, model, values, lift=go2.base_pose)


def test_tree_matches_pinocchio(tree_robot):
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(tree_robot.info["urdf"])

    def values(q):
        v = dict(zip(tree_robot.joint_names, q))
        v["j4"] = -0.5 * v["j1"] + 0.3  # mimic
        return v

    _compare_with_pin(tree_robot, model, values)


def test_concurrent_calls_do_not_interfere(tree_robot):
    """Two threads run FK on one (tree-shaped, scratch-using) robot at once: each gets its own answer."""
    from concurrent.futures import ThreadPoolExecutor

    qs = [random_q(tree_robot, 6000, seed=s) for s in (10, 11, 12, 13)]
    with ThreadPoolExecutor(2) as ex:
        results = list(ex.map(lambda q: tree_robot.fk(q)[0], qs))
    for q, c in zip(qs, results):
        np.testing.assert_allclose(c, tree_robot.ellipsoid_frames(q)[0], atol=2e-6)


@pytest.mark.parametrize("name", ["panda", "go2"])
def test_fk_of_an_ellipsoid_subset_and_of_link_frames(name):
    """Robot.fk(ellipsoids=...) gives those columns of the full FK; links=... gives link frames."""
    from splatplan.robots import load_robot

    robot = load_robot(name)
    q = random_q(robot, 64, seed=3)
    for device in devices():
        c, r = robot.fk(q, device=device)
        sub = [robot.n_ellipsoids - 1, 0, 2]  # any order
        cs, rs = robot.fk(q, device=device, ellipsoids=sub)
        np.testing.assert_array_equal(cs, c[:, sub])
        np.testing.assert_array_equal(rs, r[:, sub])
        links = [len(robot.link_names) - 1, 1]
        cl, rl = robot.fk(q, device=device, links=links)
        t = robot.link_poses(q)[:, links]
        np.testing.assert_allclose(cl, t[..., :3, 3], atol=2e-5)
        np.testing.assert_allclose(rl, t[..., :3, :3], atol=2e-5)
