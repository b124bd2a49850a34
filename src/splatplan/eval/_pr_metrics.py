"""Precision-recall metrics of study E1 (:mod:`splatplan.eval.pr`): the curve over every distinct
threshold, step-wise average precision, best F1 and a binary decision's precision/recall.

Ties form one step, as scikit-learn's ``average_precision_score``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import SplatplanError


def precision_recall_curve(
    scores: np.ndarray,  # (Q,) larger = more likely positive; finite or +-inf, no NaN
    labels: np.ndarray,  # (Q,) bool ground truth
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Precision and recall at every distinct threshold ("positive iff score >= thr").

    Returns:
        (precision, recall, thresholds), each (T,), thresholds decreasing. Tied scores form a
        single threshold.

    Raises:
        SplatplanError: shapes differ, NaN scores, or no positive label.
    """
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    y = np.asarray(labels, dtype=bool).reshape(-1)
    if s.shape != y.shape:
        raise SplatplanError(f"scores {s.shape} and labels {y.shape} differ in shape")
    if np.isnan(s).any():
        raise SplatplanError("scores contain NaN")
    n_pos = int(y.sum())
    if n_pos == 0:
        raise SplatplanError("no positive (colliding) query: precision-recall is undefined; enlarge the grid")
    order = np.argsort(-s, kind="stable")
    s, y = s[order], y[order]
    tp = np.cumsum(y)  # (Q,)
    fp = np.cumsum(~y)
    last = np.r_[np.nonzero(s[1:] != s[:-1])[0], len(s) - 1]  # last index of each tie group
    tp, fp = tp[last], fp[last]
    return tp / (tp + fp), tp / n_pos, s[last]


def average_precision(precision: np.ndarray, recall: np.ndarray) -> float:
    """Step-wise AP = sum_k (R_k - R_{k-1}) P_k (R_0 = 0), thresholds in decreasing order."""
    r_prev = np.r_[0.0, recall[:-1]]
    return float(np.sum((recall - r_prev) * precision))


def best_f1(precision: np.ndarray, recall: np.ndarray) -> tuple[float, int]:
    """(max over thresholds of 2PR / (P + R), index of that threshold)."""
    den = precision + recall
    f1 = np.where(den > 0, 2 * precision * recall / np.where(den > 0, den, 1.0), 0.0)
    k = int(np.argmax(f1))
    return float(f1[k]), k


def decision_prf(pred: np.ndarray, labels: np.ndarray) -> dict[str, float]:
    """Precision, recall, F1 of a binary decision."""
    tp = float(np.sum(pred & labels))
    fp = float(np.sum(pred & ~labels))
    fn = float(np.sum(~pred & labels))
    p = tp / (tp + fp) if tp + fp > 0 else 0.0
    r = tp / (tp + fn) if tp + fn > 0 else 0.0
    return {"precision": p, "recall": r, "f1": 2 * p * r / (p + r) if p + r > 0 else 0.0}


def pr_summary(scores: np.ndarray, labels: np.ndarray, native_threshold: float | None = None) -> dict[str, Any]:
    """AP, best F1 (+ its threshold) and, given the method's own threshold, its P/R/F1.

    Args:
        scores: (Q,) collision scores (larger = collision).
        labels: (Q,) bool ground truth.
        native_threshold: the method decides "collision" iff score > this (strict).
    """
    p, r, thr = precision_recall_curve(scores, labels)
    f1, k = best_f1(p, r)
    out: dict[str, Any] = {"ap": average_precision(p, r), "best_f1": f1, "best_f1_threshold": float(thr[k])}
    if native_threshold is not None:
        d = decision_prf(np.asarray(scores) > native_threshold, np.asarray(labels, bool))
        out.update({f"native_{k_}": v for k_, v in d.items()})
    return out


def thin_curve(p: np.ndarray, r: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """At most ~n points of a PR curve, always keeping the first and last."""
    if len(p) <= n:
        return p, r
    idx = np.unique(np.r_[np.linspace(0, len(p) - 1, n).astype(int), len(p) - 1])
    return p[idx], r[idx]
