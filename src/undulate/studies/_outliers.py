"""Outliers are findings: which runs widen a group's interval, and why.

A study that reports one RMS residual per group (per N, per xi, ...) can find a
group whose bootstrap interval is much wider than its neighbours': a few runs
differ from the rest.  This module finds that group, the runs that drive it,
and sorts each into one of three causes (:data:`CLASSES`):

* :data:`DRIFTING` -- the run had not settled: not steady by the study's rule,
  or steady only over (about) the last window of its series;
* :data:`OTHER_BRANCH` -- steady, and its nearest compatibility branch
  ``lambda (dphi/2pi + n)`` is not the branch (or either of the two branches)
  nearest the start offset: the pair moved on to another compatible state;
* :data:`OTHER_STATE` -- steady and nearest a start branch, but far from it:
  a steady state off every branch.

Note on residuals.  The residual of :func:`undulate.theory.compatibility_residual`
is the distance to the *nearest* branch, so a run that settles on another
branch has a small residual and does not widen an RMS interval: it is an
outlier of ``dx``, not of the residual.  :func:`branch_changes` lists those runs
on their own; :func:`outlying` (on the residual) finds the runs that widen the
interval, and :func:`classify` sorts them.  Such a run is :data:`OTHER_BRANCH`
only when it is both beyond the group's spread and nearer another branch than
a start branch.

Pure functions of arrays; thresholds :data:`WIDTH_FACTOR` and :data:`MAD_K`.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping

import numpy as np

__all__ = ["WIDTH_FACTOR", "MAD_K", "MAD_SCALE", "DRIFTING", "OTHER_BRANCH", "OTHER_STATE", "CLASSES",
           "width_ratios", "outlying", "nearest_branch", "start_branches", "branch_changes", "classify"]

WIDTH_FACTOR = 3.0
"""A group's interval is *wide* when its width exceeds this many times the median width of the other
groups' intervals."""
MAD_K = 3.0
"""A run drives a wide interval when its |residual| exceeds the group's median |residual| by more than
this many (normal-scaled) median absolute deviations."""
MAD_SCALE = 1.4826
"""MAD -> standard deviation for normally distributed values."""

DRIFTING = "still drifting"
OTHER_BRANCH = "another compatible branch"
OTHER_STATE = "another steady state"
CLASSES = (DRIFTING, OTHER_BRANCH, OTHER_STATE)


def width_ratios(widths: Mapping[Hashable, float]) -> dict[Hashable, float]:
    """Each group's interval width over the median width of the *other* groups' (NaN where a width or
    every other width is missing, or the others' median is 0)."""
    out = {}
    for k, w in widths.items():
        others = np.array([v for j, v in widths.items() if j != k], float)
        others = others[np.isfinite(others)]
        med = float(np.median(others)) if others.size else math.nan
        out[k] = float(w) / med if math.isfinite(float(w)) and math.isfinite(med) and med > 0 else math.nan
    return out


def outlying(residual, k: float = MAD_K) -> tuple[np.ndarray, float]:
    """``(mask, threshold)``: the runs whose |residual| exceeds ``median + k * 1.4826 * MAD`` of the
    group's finite |residual|s (NaN never outlies).  With no spread (MAD 0) only values above the common
    median are outliers."""
    a = np.abs(np.asarray(residual, float))
    fin = np.isfinite(a)
    if fin.sum() < 3:
        return np.zeros(a.shape, bool), math.nan
    med = float(np.median(a[fin]))
    mad = MAD_SCALE * float(np.median(np.abs(a[fin] - med)))
    thr = med + k * mad
    with np.errstate(invalid="ignore"):
        mask = fin & (a > thr) if mad > 0 else fin & (a > med * (1 + 1e-9) + 1e-12)
    return mask, thr


def nearest_branch(dx_over_lambda, dphi_rad) -> np.ndarray:
    """Index n of the compatibility branch ``dphi/2pi + n`` nearest each ``dx/lambda`` (the branch of
    :func:`undulate.theory.compatibility_residual`; NaN where dx is NaN)."""
    u = np.asarray(dx_over_lambda, float) - np.asarray(dphi_rad, float) / (2 * np.pi)
    with np.errstate(invalid="ignore"):
        return np.ceil(u - 0.5)


def start_branches(dphi_rad: float, start_over_lambda: float = 0.0) -> tuple[int, ...]:
    """The branch index (two at a tie, e.g. dphi = +-pi from dx0 = 0) nearest the start offset."""
    b0 = float(dphi_rad) / (2 * np.pi)
    cands = range(int(math.floor(start_over_lambda - b0)) - 1, int(math.ceil(start_over_lambda - b0)) + 2)
    d = {n: abs(b0 + n - start_over_lambda) for n in cands}
    m = min(d.values())
    return tuple(n for n, v in d.items() if v <= m + 1e-9)


def branch_changes(dx_over_lambda, dphi_rad, start_over_lambda: float = 0.0) -> np.ndarray:
    """True where a run's nearest branch is none of the branches nearest its start offset."""
    dx = np.asarray(dx_over_lambda, float)
    dphi = np.broadcast_to(np.asarray(dphi_rad, float), dx.shape)
    n = nearest_branch(dx, dphi)
    out = np.zeros(dx.shape, bool)
    for i in np.ndindex(*dx.shape):
        if math.isfinite(n[i]):
            out[i] = int(n[i]) not in start_branches(dphi[i], start_over_lambda)
    return out


def classify(drifting: bool, other_branch: bool) -> str:
    """The cause of one outlying run (:data:`CLASSES`): not settled; settled on another branch than its
    start's; else settled off every branch."""
    if drifting:
        return DRIFTING
    return OTHER_BRANCH if other_branch else OTHER_STATE
