"""The safety margin from the splat spacing (``splatplan.scenes.margin``): the typed API, its
agreement with the tuple form the MBM study uses, its input checks, and the bound it promises
(``margin >= rho + r / 2``) on a sampled scene whose exact surface is known."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.robots import load_robot
from splatplan.scenes import SplatMargin, filter_floaters, margin_for
from splatplan.scenes.builtin.primitives import AnalyticScene, make_box, splats_from_scene
from splatplan.scenes.margin import EDGE_FRACTION, covering_radius, derived_margin, splat_spacing


@pytest.fixture(scope="module")
def sampled():
    """A box on a floor sampled with the built-in real-capture look, floaters filtered as load_scene does."""
    scene = AnalyticScene(np.stack([make_box([0, 0, 0.1], [0.1, 0.08, 0.1]), make_box([0, 0, -0.01], [0.3, 0.3, 0.01])]), [], {})
    splats = splats_from_scene(scene, 6000, seed=4)
    spacing = float(splats.info["base_spacing"])
    splats, _ = filter_floaters(splats)
    return scene, splats, spacing


def test_margin_for_is_the_derived_margin_typed(sampled):
    _, splats, _ = sampled
    robot = load_robot("panda")
    for n_sigma in (0.0, 1.0, 2.0):
        got = margin_for(splats, robot, n_sigma)
        m, h, r = derived_margin(robot, splats.means, 3.0, n_sigma=n_sigma, scales=splats.scales, floor_factor=0.5)
        assert isinstance(got, SplatMargin) and got.n_sigma == n_sigma
        assert (got.margin, got.spacing, got.edge_resolution) == pytest.approx((m, h, r), rel=1e-12)
        assert got.edge_resolution == pytest.approx(EDGE_FRACTION * robot.min_semi_axis)
        assert got.covering_estimate == pytest.approx(m - 0.5 * r)
    assert margin_for(splats, robot, 2.0).margin < margin_for(splats, robot, 0.0).margin  # the splats' extent closes gaps


def test_margin_for_formula_and_options(sampled):
    _, splats, _ = sampled
    robot = load_robot("sphere:0.02")
    h = splat_spacing(splats.means)
    m = margin_for(splats, robot, edge_resolution=0.004)
    assert m.spacing == h and m.edge_resolution == 0.004 and m.margin == pytest.approx(3.0 * h + 0.002)
    m2 = margin_for(splats, robot, spacing_factor=2.0)
    assert m2.margin == pytest.approx(2.0 * h + 0.5 * EDGE_FRACTION * 0.02)
    s_t = float(np.median(np.sort(splats.scales.astype(np.float64), axis=1)[:, 1]))
    big = margin_for(splats, robot, 1000.0)  # the n_sigma reach exceeds the spacing: the floor
    assert big.margin == pytest.approx(0.5 * h + 0.5 * big.edge_resolution) and 1000.0 * s_t > 3.0 * h


def test_margin_for_rejects_bad_input(sampled):
    _, splats, _ = sampled
    robot = load_robot("sphere:0.02")
    for kw in ({"n_sigma": -1.0}, {"n_sigma": float("nan")}, {"spacing_factor": -0.1}, {"floor_factor": float("inf")}, {"edge_resolution": 0.0},
               {"edge_resolution": float("nan")}):  # fmt: skip
        with pytest.raises(SplatplanError):
            margin_for(splats, robot, **kw)
    with pytest.raises(SplatplanError, match="at least 2 splats"):
        margin_for(splats.subset(np.arange(1)), robot)
    bad = splats.subset(np.arange(10))
    bad.means[0, 0] = np.nan
    with pytest.raises(SplatplanError, match="non-finite"):
        margin_for(bad, robot)


def test_the_derived_margin_covers_the_measured_gaps(sampled):
    """The guarantee's premise, on the sampler's look: the margin from the splats alone is at least
    the measured covering radius plus half the edge resolution, at n_sigma 0 and above."""
    scene, splats, spacing = sampled
    robot = load_robot("sphere:0.01")
    for n_sigma in (0.0, 1.0):
        m = margin_for(splats, robot, n_sigma)
        rho = covering_radius(scene, splats, spacing, n_sigma=n_sigma, seed=0)
        assert 0 < rho and m.holds(rho), (n_sigma, rho, m)
        assert not m.holds(m.covering_estimate + 1e-9)  # holds() is the bound itself


def test_the_margin_at_another_n_sigma_is_the_margin_derived_there(sampled):
    """covering_at / at give, from a margin derived at one n_sigma, the margin margin_for derives at
    another (the escapes' higher-n_sigma check), down to the floor; floor_n_sigma is where it lands."""
    scene, splats, spacing = sampled
    robot = load_robot("sphere:0.01")
    m0 = margin_for(splats, robot, 0.0)
    assert m0.tangential_std == pytest.approx(float(np.median(np.sort(splats.scales.astype(np.float64), axis=1)[:, 1])))
    for n in (0.0, 0.5, 1.0, 2.0, 3.0, 50.0):
        there = margin_for(splats, robot, n)
        assert m0.covering_at(n) == pytest.approx(there.covering_estimate, rel=1e-12)
        assert m0.at(n).margin == pytest.approx(there.margin, rel=1e-12) and m0.at(n).n_sigma == n
        assert there.covering_at(0.0) == pytest.approx(m0.covering_estimate, rel=1e-12)
    n_floor = m0.floor_n_sigma
    assert n_floor is not None and n_floor > 0
    assert m0.covering_at(n_floor) == pytest.approx(0.5 * m0.spacing)
    assert m0.covering_at(0.9 * n_floor) > 0.5 * m0.spacing
    # the estimate keeps its promise where it is used: at the floor n_sigma the measured rho is below it
    rho = covering_radius(scene, splats, spacing, n_sigma=min(n_floor, 3.0), seed=0)
    assert m0.at(min(n_floor, 3.0)).holds(rho), (n_floor, rho)
    # a margin given by hand knows nothing of other n_sigma
    hand = SplatMargin(margin=0.02, spacing=0.004, edge_resolution=0.008, n_sigma=0.0)
    assert hand.covering_at(0.0) == pytest.approx(0.016) and hand.covering_at(1.0) is None and hand.at(1.0) is None
    assert hand.floor_n_sigma is None


def test_old_names_stay_importable_from_the_mbm_study():
    from splatplan.eval import mbm
    from splatplan.scenes import margin

    assert mbm.covering_radius is margin.covering_radius and mbm.derived_margin is margin.derived_margin
