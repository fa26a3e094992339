"""How often the 95 % interval of a slope fitted over clustered rows (the neighbour pairs of a group's
runs) holds the true slope, for three intervals:

* ``rows' t``: :func:`undulate.stats.line_fit`, every row an independent point (``n - 2`` degrees of
  freedom): the groups' slope until 2026-12-02;
* ``CR1``: the cluster-robust sandwich with its small-sample factor ``G / (G - 1) (n - 1) / (n - 2)``,
  Student's t on ``G - 1`` (what ``statsmodels`` gives with ``cov_type="cluster"``);
* ``CR3``: the cluster jackknife with t on ``G - 1``, :func:`undulate.stats.clustered_line_fit` (the
  package's since 2026-12-02; each trial's standard error is checked against it on the first trials).

Rows (each with slope 1): runs of rows at one x sharing a run effect; groups of three (phases
(0, dphi, 2 dphi): both neighbour pairs at dphi, the middle swimmer's position error entering them with
opposite signs); groups of four (random phases, each swimmer's error in its two neighbour pairs);
independent rows.  Usage: ``python explorations/cluster_coverage.py [--trials 3000] [--seed 1]``; a
markdown table on stdout (docs/verdicts.md, "Staged runs").  It measures; nothing is asserted.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy import stats as st

from undulate import stats


def _fits(x, y, g):
    """(slope, rows' se and dof, CR1 se, CR3 se, G - 1)."""
    X = np.column_stack([np.ones_like(x), x])
    n = x.size
    b = np.linalg.lstsq(X, y, rcond=None)[0]
    e = y - X @ b
    xtx = np.linalg.inv(X.T @ X)
    se_rows = np.sqrt(e @ e / (n - 2) * xtx[1, 1])
    labels = np.unique(g)
    G = labels.size
    meat, jack = np.zeros((2, 2)), []
    for k in labels:
        m = g == k
        s = X[m].T @ e[m]
        meat += np.outer(s, s)
        jack.append(np.linalg.lstsq(X[~m], y[~m], rcond=None)[0][1])
    v1 = G / (G - 1) * (n - 1) / (n - 2) * xtx @ meat @ xtx
    v3 = (G - 1) / G * np.sum((np.array(jack) - b[1]) ** 2)
    return b[1], se_rows, n - 2, np.sqrt(v1[1, 1]), np.sqrt(v3), G - 1


def _run_effect(G, m, rng):
    x = np.repeat(rng.uniform(-1, 1, G), m)
    g = np.repeat(np.arange(G), m)
    return x, x + rng.normal(0, 1.0, G)[g] + rng.normal(0, 0.1, G * m), g


def _threes(G, rng):
    d = rng.uniform(-1, 1, G)
    pos = rng.normal(0, 0.3, (G, 3))
    e = np.column_stack([pos[:, 1] - pos[:, 0], pos[:, 2] - pos[:, 1]]).ravel()
    return np.repeat(d, 2), np.repeat(d, 2) + e, np.repeat(np.arange(G), 2)


def _fours(G, rng):
    phase = rng.uniform(-0.5, 0.5, (G, 4))
    pos = rng.normal(0, 0.3, (G, 4))
    x = np.diff(phase, axis=1).ravel()
    return x, x + np.diff(pos, axis=1).ravel(), np.repeat(np.arange(G), 3)


def _independent(G, m, rng):
    x = rng.uniform(-1, 1, G * m)
    return x, x + rng.normal(0, 0.3, G * m), np.repeat(np.arange(G), m)


CASES = {
    "12 runs of 2 rows at one x, a run effect (sd 1; rows 0.1)": lambda r: _run_effect(12, 2, r),
    "5 runs of 2 rows, the same": lambda r: _run_effect(5, 2, r),
    "4 runs of 3 rows, the same": lambda r: _run_effect(4, 3, r),
    "groups of three, 12 runs": lambda r: _threes(12, r),
    "groups of three, 5 runs": lambda r: _threes(5, r),
    "groups of four, 10 runs": lambda r: _fours(10, r),
    "groups of four, 4 runs": lambda r: _fours(4, r),
    "independent rows, 12 runs of 2": lambda r: _independent(12, 2, r),
    "independent rows, 5 of 2": lambda r: _independent(5, 2, r),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=3000)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    print("| rows | rows' t | CR1, t on G - 1 | CR3, t on G - 1 |\n|---|---:|---:|---:|")
    for name, make in CASES.items():
        hits = np.zeros(3)
        for t in range(a.trials):
            x, y, g = make(rng)
            b, se_r, dof_r, se1, se3, dof_g = _fits(x, y, g)
            if t < 3:  # the package's CR3 is this one
                assert np.isclose(stats.clustered_line_fit(x, y, g).slope.stderr, se3, rtol=1e-9)
            qr, qg = st.t.ppf(0.975, dof_r), st.t.ppf(0.975, dof_g)
            hits += np.abs(b - 1) <= np.array([qr * se_r, qg * se1, qg * se3])
        cov = hits / a.trials
        print(f"| {name} | {cov[0]:.1%} | {cov[1]:.1%} | {cov[2]:.1%} |".replace("%", " %"))


if __name__ == "__main__":
    main()
