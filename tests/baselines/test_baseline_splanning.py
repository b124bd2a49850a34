"""SPLANNING cube integral against Monte Carlo integration of o * N(x; mu, Sigma) over the cube."""

from __future__ import annotations

import math

import numpy as np
import torch
from scipy.stats import multivariate_normal

from splatplan.baselines.splanning import Splanning, collision_from_score, splanning_score
from splatplan.scenes.splats import Splats


def _single(sc: dict, i: int) -> dict:
    return {k: sc[k][i : i + 1] for k in ("means", "quats", "scales", "opacities")}


def _cov(sc: dict, i: int) -> np.ndarray:
    # Covariance through the project's numpy Splats (independent of the torch rotation code).
    sp = Splats(means=sc["means"][i : i + 1], quats=sc["quats"][i : i + 1], scales=sc["scales"][i : i + 1],
                opacities=sc["opacities"][i : i + 1], colors=np.zeros((1, 3)))
    return sp.covariances()[0]


def test_integral_matches_monte_carlo(make_scene):
    # Anisotropic rotated Gaussians with scales comparable to r, centres at varied offsets. The
    # cube is axis-aligned in each Gaussian's principal frame: {x : |R^T (x - c)|_inf <= r}.
    sc = make_scene(8, seed=21, smin=0.01, smax=0.06, spread=0.05)
    rng = np.random.default_rng(22)
    r = 0.03
    n_mc = 200_000
    for i in range(8):
        cov = _cov(sc, i)
        rot = sc["rot"][i]
        for c in sc["means"][i] + rng.normal(size=(2, 3)) * 0.03:
            ours = [Splanning(_single(sc, i), dtype=dt).integral(c[None], r)[0] for dt in (torch.float64, torch.float32)]
            # (a) sample the Gaussian, count hits in the cube.
            x = rng.multivariate_normal(sc["means"][i], cov, n_mc)
            hit = np.all(np.abs((x - c) @ rot) <= r, axis=1)
            mc_a = sc["opacities"][i] * hit.mean()
            # (b) sample the cube uniformly, average the density (scipy pdf from the covariance).
            u = rng.uniform(-r, r, (n_mc, 3))
            mc_b = sc["opacities"][i] * (2 * r) ** 3 * multivariate_normal(sc["means"][i], cov).pdf(c + u @ rot.T).mean()
            for mc in (mc_a, mc_b):
                for val in ours:
                    assert abs(val - mc) <= 0.004 + 0.02 * mc, (i, ours, mc_a, mc_b)


def test_sum_probability_and_culling(make_scene):
    sc = make_scene(60, seed=4, smin=0.005, smax=0.03, spread=0.08)
    c = np.random.default_rng(3).normal(size=(25, 3)) * 0.1
    r = 0.02
    sp = Splanning(sc, dtype=torch.float64)
    total = sp.integral(c, r)
    parts = np.stack([Splanning(_single(sc, i), dtype=torch.float64, cull_std=1e9).integral(c, r) for i in range(60)], 1)
    # Culling at 6 s_max + r is not exact: the cube's corners reach r sqrt(3) from c, i.e. within
    # 6 s_max - 0.73 r of a culled mean, so a culled Gaussian can still hold a ~1e-6 tail mass.
    np.testing.assert_allclose(total, parts.sum(1), rtol=1e-9, atol=1e-5)
    uncut = Splanning(sc, dtype=torch.float64, cull_std=1e9).integral(c, r)
    np.testing.assert_allclose(uncut, parts.sum(1), rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(sp.score(c, r), 1 - np.exp(-total / (4 * math.pi)), rtol=1e-12, atol=1e-15)
    # Dense blocks over queries and Gaussians give the same sums.
    np.testing.assert_allclose(Splanning(sc, dtype=torch.float64, max_elems=7 * 3 * 5).integral(c, r, batch=7), total, rtol=1e-12)


def test_2dgs_disks_and_alpha(make_scene):
    sc = make_scene(20, seed=8)
    sc["scales"][:, 2] = 0.0
    c = np.concatenate([sc["means"][:3], sc["means"][:3] + 5.0])
    p = splanning_score(sc, c, 0.015)
    assert np.isfinite(p).all() and (p[:3] > 0).all() and (p[3:] == 0).all()
    assert collision_from_score(np.array([0.02, 0.005])).tolist() == [True, False]
