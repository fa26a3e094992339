"""How often the intervals of a root mean square and a standard deviation miss the true value.

A claim such as "the RMS residual lies below 0.1 lambda" holds on the interval's upper bound, so an
upper bound below the truth more often than its nominal 2.5 % makes ``holds`` too easy.  For seeded
samples of known distributions (normal about zero and off zero, Student's t with 4 degrees of
freedom, a normal with 10 % of points five times wider, uniform) and sizes 5-49, this prints the
fraction of trials whose 95 % interval lies wholly below the truth ("upper miss") and wholly above
it ("lower miss"), for:

* ``expanded BCa``: :func:`undulate.stats.rms` / :func:`undulate.stats.std`, the package's interval
  since 2026-11-29 (later): the bias-corrected and accelerated interval of
  :func:`undulate.stats.bootstrap` at Hesterberg's expanded levels (:func:`undulate.stats.expanded_z`);
* ``BCa``: the same with the textbook normal quantile (``expand=False``; the package's method
  earlier on 2026-11-29);
* ``percentile``: the percentile bootstrap of the same statistic at the textbook levels (the
  package's method before);
* ``studentized``: a bootstrap-t on the log of the mean square (the same 2000 resamples), tried
  and set aside: it covers better on normal samples, but a resample whose squares are (nearly)
  equal divides by a (nearly) zero spread, and the studies' residuals come in mirror pairs with
  equal squares.

Usage: ``python explorations/interval_coverage.py [--trials 400] [--pairs | --median]``; a markdown
table on stdout (docs/verdicts.md, "How an interval is formed").  ``--pairs``: BCa and percentile
intervals of R^2 and Spearman's rho on bivariate normal samples (R^2 is BCa in the package since
2026-11-29, Spearman's rho stays percentile); ``--median``: the same for a median (stays percentile).
"""

from __future__ import annotations

import argparse
import math
import numpy as np
from undulate import stats

DISTRIBUTIONS = {
    "normal(0, 1)": (lambda r, n: r.normal(0, 1, n), 1.0, 1.0),
    "normal(0.5, 1)": (lambda r, n: r.normal(0.5, 1, n), math.sqrt(1.25), 1.0),
    "t, 4 dof": (lambda r, n: r.standard_t(4, n), math.sqrt(2.0), math.sqrt(2.0)),
    "10 % five times wider": (lambda r, n: np.where(r.random(n) < 0.1, r.normal(0, 5, n), r.normal(0, 1, n)),
                              math.sqrt(3.4), math.sqrt(3.4)),
    "uniform(-1, 1)": (lambda r, n: r.uniform(-1, 1, n), math.sqrt(1 / 3), math.sqrt(1 / 3)),
}
SIZES = (5, 9, 17, 30, 49)
VARIANTS = {"expanded BCa": ("BCa", True), "BCa": ("BCa", False),
            "expanded percentile": ("percentile", True), "percentile": ("percentile", False)}
"""The paired tables' intervals: each method at Hesterberg's expanded levels (the package's since
2026-11-29, later) and at the textbook ones."""


def _rms_rows(a, axis=-1):
    return np.sqrt(np.mean(a * a, axis=axis))


def _std_rows(a, axis=-1):
    return np.std(a, axis=axis)


def _studentized(x: np.ndarray, centred: bool) -> tuple[float, float]:
    """Bootstrap-t on ``log mean(c**2)``: (low, high) of the root mean square (NaN where degenerate)."""
    n = x.size
    idx = np.random.default_rng(stats.BOOTSTRAP_SEED).integers(0, n, (stats.N_RESAMPLES, n))
    xb = x[idx]
    c, cb = (x - x.mean(), xb - xb.mean(axis=1, keepdims=True)) if centred else (x, xb)
    y, yb = c * c, cb * cb
    m0, mb = y.mean(), yb.mean(axis=1)
    with np.errstate(all="ignore"):
        t = (np.log(mb) - np.log(m0)) / (yb.std(axis=1, ddof=1) / (mb * math.sqrt(n)))
        se0 = y.std(ddof=1) / (m0 * math.sqrt(n))
        q_lo, q_hi = np.quantile(t[np.isfinite(t)], [0.025, 0.975])
        return float(np.sqrt(m0 * np.exp(-q_hi * se0))), float(np.sqrt(m0 * np.exp(-q_lo * se0)))


def intervals(x: np.ndarray, which: str) -> dict[str, tuple[float, float]]:
    """Each method's 95 % interval of ``which`` ("rms" or "std") of the sample ``x``."""
    e = getattr(stats, which)(x)
    rows = _rms_rows if which == "rms" else _std_rows
    _, blo, bhi = stats.bootstrap(rows, x, vectorized=True, expand=False)
    _, lo, hi = stats.bootstrap(rows, x, vectorized=True, method="percentile", expand=False)
    return {"expanded BCa": (e.low, e.high), "BCa": (blo, bhi), "percentile": (lo, hi),
            "studentized": _studentized(x, which == "std")}


def _pairs_table(trials: int) -> None:
    """R^2 of a line fit and Spearman's rho on bivariate normal samples (correlation rho): the paired
    BCa and percentile intervals of the same resamples (``stats.bootstrap``).  The package forms R^2's
    by BCa (``stats.line_fit``; percentile until 2026-11-29) and keeps Spearman's percentile one
    (``stats.rank_correlation``: BCa gains nothing on it)."""
    from scipy import stats as st

    def r2_rows(a, b, axis=-1):
        return stats._pearson_rows(a, b, axis) ** 2

    def rho_rows(a, b, axis=-1):
        return stats._pearson_rows(st.rankdata(a, axis=axis), st.rankdata(b, axis=axis), axis)

    print("\n| statistic | rho | n | " + " | ".join(f"{m}: upper / lower miss" for m in VARIANTS) + " |")
    print("|---|---:|---:|" + "---|" * len(VARIANTS))
    for which, rows in (("R^2", r2_rows), ("Spearman", rho_rows)):
        for rho in (0.9, 0.95):
            truth = rho ** 2 if which == "R^2" else 6 / math.pi * math.asin(rho / 2)
            for n in (5, 9, 17, 37):
                rng = np.random.default_rng(5)
                miss = {m: [0, 0] for m in VARIANTS}
                for _ in range(trials):
                    x = rng.normal(size=n)
                    y = rho * x + math.sqrt(1 - rho ** 2) * rng.normal(size=n)
                    for m, (method, expand) in VARIANTS.items():
                        _, low, high = stats.bootstrap(rows, x, y, vectorized=True, method=method, expand=expand)
                        miss[m][0] += truth > high
                        miss[m][1] += truth < low
                cells = " | ".join(f"{100 * u / trials:.1f} / {100 * lo / trials:.1f} %" for u, lo in miss.values())
                print(f"| {which} | {rho} | {n} | {cells} |", flush=True)


def _median_table(trials: int) -> None:
    """The median (the synchronization study's force ratio): BCa against percentile on skewed and
    normal samples.  The median is not a smooth statistic: its jackknife, which sets BCa's acceleration,
    takes two values, and BCa gains nothing here (the package keeps the percentile interval for it)."""
    def med(a, axis=-1):
        return np.median(a, axis=axis)

    print("\n| statistic | sample | n | " + " | ".join(f"{m}: upper / lower miss" for m in VARIANTS) + " |")
    print("|---|---|---:|" + "---|" * len(VARIANTS))
    samples = {"lognormal(0, 1)": (lambda r, n: r.lognormal(0, 1, n), 1.0),
               "exponential(1)": (lambda r, n: r.exponential(1, n), math.log(2)),
               "normal(0, 1)": (lambda r, n: r.normal(0, 1, n), 0.0)}
    for name, (draw, truth) in samples.items():
        for n in (9, 17, 49):
            rng = np.random.default_rng(7)
            miss = {m: [0, 0] for m in VARIANTS}
            for _ in range(trials):
                x = draw(rng, n)
                for m, (method, expand) in VARIANTS.items():
                    _, lo, hi = stats.bootstrap(med, x, vectorized=True, method=method, expand=expand)
                    miss[m][0] += truth > hi
                    miss[m][1] += truth < lo
            cells = " | ".join(f"{100 * u / trials:.1f} / {100 * lo / trials:.1f} %" for u, lo in miss.values())
            print(f"| median | {name} | {n} | {cells} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=400)
    ap.add_argument("--pairs", action="store_true", help="R^2 and Spearman's rho instead (paired samples)")
    ap.add_argument("--median", action="store_true", help="the median instead (skewed and normal samples)")
    args = ap.parse_args()
    if args.pairs or args.median:
        (_pairs_table if args.pairs else _median_table)(args.trials)
        return
    methods = ("expanded BCa", "BCa", "percentile", "studentized")
    print("| statistic | sample | n | " + " | ".join(f"{m}: upper / lower miss" for m in methods) + " |")
    print("|---|---|---:|" + "---|" * len(methods))
    for which in ("rms", "std"):
        for name, (draw, true_rms, true_sd) in DISTRIBUTIONS.items():
            truth = true_rms if which == "rms" else true_sd
            for n in SIZES:
                rng = np.random.default_rng(7)
                miss = {m: [0, 0] for m in methods}
                for _ in range(args.trials):
                    for m, (lo, hi) in intervals(draw(rng, n), which).items():
                        miss[m][0] += truth > hi
                        miss[m][1] += truth < lo
                cells = " | ".join(f"{100 * u / args.trials:.1f} / {100 * lo / args.trials:.1f} %"
                                   for u, lo in miss.values())
                print(f"| {which} | {name} | {n} | {cells} |", flush=True)


if __name__ == "__main__":
    main()
