"""E1 precision-recall: AP/F1 against hand-computed examples, exact culling, the quick study."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import torch

from splatplan.baselines import BASELINES, as_scene_tensors
from splatplan.errors import SplatplanError
from splatplan.eval._pr_culling import cull_rule, culled_collision_scores
from splatplan.eval.pr import PRConfig, PRResult, average_precision, best_f1, markdown, pr_summary, precision_recall_curve, report, run
from splatplan.scenes.splats import Splats


def _ap_f1(scores, labels):
    p, r, _ = precision_recall_curve(np.asarray(scores, float), np.asarray(labels, bool))
    return average_precision(p, r), best_f1(p, r)[0]


# ------------------------------------------------------------------ metrics, by hand
def test_ap_f1_hand_example():
    # ranks: + - + -  -> (P, R) = (1, .5), (.5, .5), (2/3, 1), (.5, 1)
    ap, f1 = _ap_f1([0.9, 0.8, 0.7, 0.6], [1, 0, 1, 0])
    assert ap == pytest.approx(0.5 * 1 + 0 * 0.5 + 0.5 * 2 / 3)
    assert f1 == pytest.approx(0.8)  # at threshold 0.7: 2 (2/3)(1) / (5/3)


def test_ties_form_one_step():
    # threshold 1: tp 1, fp 1 -> (.5, .5); threshold 0: tp 2, fp 1 -> (2/3, 1)
    p, r, thr = precision_recall_curve(np.array([1.0, 1.0, 0.0]), np.array([True, False, True]))
    np.testing.assert_allclose(p, [0.5, 2 / 3])
    np.testing.assert_allclose(r, [0.5, 1.0])
    np.testing.assert_array_equal(thr, [1.0, 0.0])
    assert average_precision(p, r) == pytest.approx(0.5 * 0.5 + 0.5 * 2 / 3)
    assert best_f1(p, r)[0] == pytest.approx(0.8)


def test_infinite_scores_and_perfect_ranking():
    ap, f1 = _ap_f1([np.inf, -np.inf, -np.inf], [1, 0, 1])  # -inf ties must not split
    assert ap == pytest.approx(0.5 + 0.5 * 2 / 3)
    assert f1 == pytest.approx(0.8)
    assert _ap_f1([3, 2, 1, 0], [1, 1, 0, 0]) == (pytest.approx(1.0), pytest.approx(1.0))
    assert _ap_f1([0, 0, 0, 0], [1, 0, 0, 0])[0] == pytest.approx(0.25)  # one tie group: AP = prevalence


def test_ap_matches_definition_on_random_ties():
    rng = np.random.default_rng(0)
    s = rng.integers(0, 12, 300).astype(float)
    y = rng.random(300) < 0.3 + 0.04 * s
    ap = 0.0
    r_prev = 0.0
    for t in sorted(set(s), reverse=True):  # brute force: every distinct threshold
        pred = s >= t
        p_t, r_t = (pred & y).sum() / pred.sum(), (pred & y).sum() / y.sum()
        ap += (r_t - r_prev) * p_t
        r_prev = r_t
    assert _ap_f1(s, y)[0] == pytest.approx(ap)


def test_native_decision_and_bad_input():
    d = pr_summary(np.array([2.0, 1.0, 0.5, -1.0]), np.array([True, False, True, False]), native_threshold=0.7)
    assert (d["native_precision"], d["native_recall"]) == (pytest.approx(0.5), pytest.approx(0.5))
    with pytest.raises(SplatplanError, match="no positive"):
        precision_recall_curve(np.ones(3), np.zeros(3, bool))
    with pytest.raises(SplatplanError, match="NaN"):
        precision_recall_curve(np.array([np.nan, 1.0]), np.array([True, False]))


# ------------------------------------------------------------------ culling is exact
def _random_scene(n: int, seed: int) -> Splats:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    s = np.exp(rng.normal(np.log(0.004), 0.8, (n, 3)))  # heavy-tailed sizes
    s[:, 2] *= 0.2
    return Splats(
        means=rng.uniform(-0.15, 0.15, (n, 3)),
        quats=q / np.linalg.norm(q, axis=1, keepdims=True),
        scales=s,
        opacities=rng.uniform(0.1, 1.0, n),
        colors=np.full((n, 3), 0.5),
    )


@pytest.mark.parametrize("name", ["splatnav", "safersplat", "atlasnav", "splanning"])
def test_culled_scores_equal_full_scores(name):
    r = 0.015
    scene_t = as_scene_tensors(_random_scene(600, 1), "cpu", torch.float32)
    q = np.random.default_rng(2).uniform(-0.2, 0.2, (300, 3))
    info = BASELINES[name]
    full_obj = info.cls(scene_t, "cpu")
    full = full_obj.collision_score(q, r, batch=64)
    incl, clamp, _ = cull_rule(name, full_obj, r)
    got, clamped, n_pairs = culled_collision_scores(info.cls, scene_t, incl, clamp, q, r, tile=0.03, block=0.09)
    assert 0 < n_pairs < 300 * 600  # culling did cull
    if clamp is None:
        assert not clamped.any()
        np.testing.assert_allclose(got, full, rtol=1e-5, atol=1e-12)
    else:
        assert clamped.any() and (~clamped).any()
        np.testing.assert_allclose(got[~clamped], full[~clamped], rtol=1e-6, atol=1e-9)
        assert np.all(full[clamped] <= clamp + 1e-9)  # the true score is beyond the clamp
        np.testing.assert_array_equal(got[clamped], clamp)


# ------------------------------------------------------------------ the quick study
@pytest.fixture(scope="module")
def quick_pr(tmp_path_factory):
    out = tmp_path_factory.mktemp("pr")
    res = run(PRConfig.quick_config())
    written = report(res, out)
    assert [p.name for p in written] == ["pr.json", "pr.md", "pr.png"]
    return out, res.to_json()


def test_quick_pr_outputs(quick_pr):
    out, res = quick_pr
    data = json.loads((out / "pr.json").read_text())
    assert isinstance(data["n_queries"], int) and isinstance(data["n_positive"], int)
    assert 0 < data["n_positive"] < data["n_queries"]
    for key in ("collisionsplatting", "splatnav", "safersplat", "atlasnav", "splanning", "collisionsplatting_nsigma0", "collisionsplatting_nsigma2"):
        m = data["methods"][key]
        assert isinstance(m["ap"], float) and 0.0 <= m["ap"] <= 1.0, key
        assert isinstance(m["best_f1"], float) and 0.0 <= m["best_f1"] <= 1.0, key
        assert 0.0 <= m["all_points"]["ap"] <= 1.0
    assert data["quick"] is True and "quick" in data["note"]
    for chk in data["culling_check"].values():
        assert chk["max_rel_dev"] < 1e-4 and chk["max_clamp_violation"] == 0.0
    assert (out / "pr.png").stat().st_size > 10_000
    md = (out / "pr.md").read_text()
    assert "| method |" in md and "Splat-Nav" in md and "SPLANNING" in md
    assert markdown(PRResult(**data)) == md  # the tables are a function of the JSON alone


def test_quick_pr_keeps_the_full_runs_ap_order(quick_pr):
    """The quick study's qualitative result is the full run's (benchmarks/results/pr.md): the
    unconservative metric (n_sigma = 0) and SPLANNING lead, CollisionSplatting (n_sigma = 1, 2) and
    Splat-Nav follow on par with them, then SAFER-Splat, and AtlasNav is last by far."""
    _, res = quick_pr
    ap = {k: m["ap"] for k, m in res["methods"].items()}
    order = sorted(ap, key=ap.get, reverse=True)
    assert set(order[:2]) == {"collisionsplatting_nsigma0", "splanning"}, ap
    assert set(order[2:5]) == {"collisionsplatting", "collisionsplatting_nsigma2", "splatnav"}, ap
    assert order[5:] == ["safersplat", "atlasnav"], ap
    assert ap["splanning"] - ap["collisionsplatting"] < 0.1 and ap["atlasnav"] < 0.8 * ap["collisionsplatting"], ap


def test_scene_path_needs_ground_truth(tmp_path):
    with pytest.raises(SplatplanError, match="--gt"):
        run(replace(PRConfig.quick_config(), scene=str(tmp_path / "scene.ply"), gt=None))
    with pytest.raises(SplatplanError, match="built-in"):
        run(replace(PRConfig.quick_config(), scene="stonehenge", gt="x.gt.json"))
    with pytest.raises(SplatplanError, match="device"):
        run(replace(PRConfig.quick_config(), device="tpu"))
    assert list(tmp_path.iterdir()) == []  # run writes nothing


def test_quick_pr_fidelity_variants(quick_pr):
    out, res = quick_pr
    v = res["variants"]
    assert set(v) == set(res["config"]["variants"])
    for ns_key, key in (("0", "collisionsplatting_nsigma0"), ("1", "collisionsplatting"), ("2", "collisionsplatting_nsigma2")):
        # (a) is today's setting: exactly the main table's row
        assert v["default"]["by_n_sigma"][ns_key]["ap"] == pytest.approx(res["methods"][key]["ap"], abs=1e-12)
    # opacity_min = t on the default scene removes the same splats as the o < t evaluation filter
    assert res["config"]["opacity_min"] == res["config"]["eval_opacity_below"]
    for k in v["opacity_filter"]["by_n_sigma"]:
        assert v["opacity_min"]["by_n_sigma"][k]["ap"] == pytest.approx(v["opacity_filter"]["by_n_sigma"][k]["ap"], abs=1e-9)
    # at n_sigma = 0 the inflation options change nothing
    assert v["opacity_scaled_inflation"]["by_n_sigma"]["0"]["ap"] == pytest.approx(v["default"]["by_n_sigma"]["0"]["ap"], abs=1e-12)
    assert v["log_mean_exp"]["metric"] == {"softmin_mode": "mean", "softmin_t": res["config"]["lme_t"]}
    # the sharp log-mean-exp does not underflow in the float32 kernel
    for chk in res["softmin_check"].values():
        assert chk["n"] > 0 and chk["n_inf_mismatch"] == 0 and chk["max_abs_dev"] < 1e-3
    md = (out / "pr.md").read_text()
    assert "fidelity variants" in md and "beyond the paper" in md and md.count("(`opacity_") >= 2


def test_results_file_resumes(tmp_path):
    """run(..., results=PATH): the scoring tasks stream to PATH; a rerun skips them and gives the same numbers."""
    cfg = replace(PRConfig.quick_config(), n_splats=4000, spacing=0.06, n_sigmas=(1.0,), baselines=("splanning",), variants=("default",), n_check=1, n_check_clamped=0)
    path = tmp_path / "pr.results.jsonl"
    first = run(cfg, results=path)
    n_lines = len(path.read_text().splitlines())
    assert n_lines == 3  # splanning, CollisionSplatting at n_sigma 1, variant (a) at n_sigma 1
    second = run(cfg, results=path)
    assert len(path.read_text().splitlines()) == n_lines  # nothing rerun
    for key in ("collisionsplatting", "splanning"):
        assert second.methods[key]["ap"] == first.methods[key]["ap"]
    assert second.engine == {"kind": "serial"}
    assert {p.name for p in tmp_path.iterdir()} <= {"pr.results.jsonl", "pr.results.jsonl.arrays"}  # run writes nothing else
