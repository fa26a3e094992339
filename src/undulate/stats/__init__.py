"""Fitted numbers with their uncertainty, on :mod:`scipy.stats`.

Every number a study fits (a slope, an RMS residual, a threshold, a
stiffness, an R^2, a rank correlation) is an :class:`Estimate`: the value,
its standard error where one is defined, and a 95 % interval with the method
that gave it.  Bootstrap intervals are seeded (:data:`BOOTSTRAP_SEED` unless
given), so the same data give the same interval.

* :func:`line_fit` -- least squares ``y = slope x + intercept``
  (``scipy.stats.linregress``: standard errors of slope and intercept; the
  interval is Student's t with ``n - 2`` degrees of freedom; R^2 with a
  paired BCa bootstrap interval).
* :func:`mirrored_line_fit`, :func:`clustered_line_fit` -- the same fit where rows are not
  independent: a mirror-symmetric design's pairs, or clusters of rows that may share their errors
  (a cluster jackknife, CR3).
* :func:`rank_correlation` -- Spearman's rho (``scipy.stats.spearmanr``:
  tied values get their average rank) with a paired percentile bootstrap interval, none where
  too few orderings exist for any to exclude rho = 0 at the level.
* :func:`rms`, :func:`std` -- root mean square, standard deviation, with a BCa bootstrap
  interval.
* :func:`mean` -- mean with its standard error (t interval).
* :func:`bootstrap` -- any statistic of one or more paired samples; bias-corrected and
  accelerated (BCa) unless asked for the plain percentile interval, which undercovers
  the upper side of an RMS, a standard deviation or an R^2 (docs/verdicts.md); either at
  Hesterberg's expanded levels (:func:`expanded_z`: a bootstrap of few points is too narrow).

Intervals that cannot be formed (too few points, a degenerate resample) are
NaN; :meth:`Estimate.to_dict` turns NaN into ``None`` for JSON.

**Domains.**  A reported number and its interval stay inside the quantity's physical domain (a
density or a width is not negative, an R^2 is at most 1, a correlation lies in [-1, 1], a count is
not negative, a fraction lies in [0, 1]): :data:`DOMAINS` names the domain of a summary key by its
name, and :func:`domain_violations` walks a study's summary and claim values for numbers outside
theirs (:func:`undulate.claims.collect` refuses a study that reports one).  An interval that leaves
its domain comes from a method that does not fit its quantity (a t interval on two draws of a
density reached -2.02), and is fixed there, never clipped.

**Repeated looks.**  A study that adds runs in stages looks at its intervals
after every stage (:mod:`undulate.studies._registry`).  Every interval of a
look is formed at the level :func:`level` returns, which the registry sets
for the look with :func:`at_level` (:func:`look_levels`: the family-wise
``1 - CONFIDENCE`` split over the looks, Bonferroni); ``ci95`` in
:meth:`Estimate.to_dict` is that interval and ``level`` its level.  Outside a
look the level is :data:`CONFIDENCE`.

The package's modules: :mod:`._levels` (the looks' levels), :mod:`._estimate` (:class:`Estimate`,
:class:`Check` and the runs a check needs), :mod:`._bootstrap`, :mod:`._fits` and :mod:`._domains`;
every public name is imported here.
"""

from __future__ import annotations

from ._levels import (  # noqa: F401
    CONFIDENCE, LOOK_SHARES, at_level, interval_note, level, look_levels, plan_level)
from ._levels import _confidence as check_confidence  # noqa: F401 - undulate.stopping validates its level with it
from ._estimate import (  # noqa: F401
    Check, Estimate, NAN, all_of, decide, half_width_at, runs_needed)
from ._bootstrap import (  # noqa: F401
    BOOTSTRAP_METHODS, BOOTSTRAP_SEED, N_RESAMPLES, bootstrap, expanded_z)
from ._fits import (  # noqa: F401
    CLUSTERED_SLOPE_METHOD, LineFit, clustered_line_fit, is_mirror_design, joined_clusters, line_fit, mean,
    mirrored_line_fit, rank_correlation, rank_correlation_points, rms, std)
from ._domains import (  # noqa: F401
    DOMAINS, check_domains, domain_of, domain_violations, estimates)

__all__ = ["Estimate", "LineFit", "line_fit", "mirrored_line_fit", "clustered_line_fit", "joined_clusters",
           "is_mirror_design", "rank_correlation", "rms",
           "std", "mean", "bootstrap", "expanded_z", "BOOTSTRAP_SEED", "N_RESAMPLES", "CONFIDENCE", "level", "at_level",
           "look_levels", "plan_level", "interval_note", "Check", "decide", "all_of", "runs_needed",
           "half_width_at", "DOMAINS", "domain_of", "domain_violations", "check_domains", "check_confidence"]
