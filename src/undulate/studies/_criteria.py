"""The criteria the studies judge the paper's claims by, and the channels they judge them in.

Stated once here and imported by every study (and by the explanations that
re-judge a claim under another model choice), so that a claim and its
explanation can never be judged by two different numbers.  Lengths in m;
offsets in wavelengths lambda (L for the standing wave xi = 0).
"""

from __future__ import annotations

__all__ = [
    "PAIR_CHANNEL_M",
    "GROUP_CHANNEL_M",
    "STEADY_TOL",
    "STEADY_WINDOW",
    "LINE_SLOPE_TOL",
    "LINE_RMS_TOL",
    "GROUP_SLOPE_TOL",
    "GROUP_RMS_TOL",
    "R2_MIN",
    "WIDTH_TOL",
    "CENTRAL",
    "RETURN_TOL",
    "LINKS_TREND_RULE",
    "CONFINEMENT_TREND_RULE",
]

PAIR_CHANNEL_M = 0.13
"""Channel width d of every pair run (the paper's 13 cm), m."""
GROUP_CHANNEL_M = {3: 0.19, 4: 0.22}
"""Channels of the groups of three and four (the paper's), m."""

STEADY_TOL = 0.01
"""Steady-state rule: the last :data:`STEADY_WINDOW` period means of dx/lambda lie within this of their
mean (dimensionless)."""
STEADY_WINDOW = 3
"""Periods in the steady-state window."""

LINE_SLOPE_TOL = 0.2
""""Follows the compatibility line" (pairs): the slope's 95 % interval inside 1 +- this."""
LINE_RMS_TOL = 0.1
""""Follows the compatibility line" (pairs): the upper 95 % bound of the RMS distance from the nearest
branch below this many wavelengths."""
GROUP_SLOPE_TOL = 0.2
"""Groups "follow the line": the slope's 95 % interval inside 1 +- this."""
GROUP_RMS_TOL = 0.2
"""Groups "follow the line with more scatter": RMS residual below this many wavelengths (twice the
pairs' tolerance) and wholly above the reference pairs'."""
R2_MIN = 0.9
""""Linear" (potential study): the lower 95 % bound of R^2 at least this."""
WIDTH_TOL = 0.01
"""Confinement: width (lambda) of the set of starts ending in the central state above which it is open."""
CENTRAL = 0.5
"""Confinement: a start ends in the central state when its final |dx/lambda| is below this."""
RETURN_TOL = 0.05
"""Basins: a dphi = 0 start returns to the compatible state when its final |dx/lambda| is below this."""

LINKS_TREND_RULE = (
    "the least-squares slope of every run's squared residual (lambda^2) against N, over the whole range of N "
    "(3 to 9), with its 95 % interval from the cluster jackknife over the design points (CR3, Student's t on "
    "G - 1: a design point is one |dphi|, its runs at every N, +dphi and -dphi together), lies wholly below 0: "
    "holds; wholly above 0: fails; straddles 0: undecided.  The paper gives no size of the fall (values "
    "withheld), so no band of no change is fixed from its words: a flat trend stays undecided")
"""The link-number claim ("the RMS error ... decreased with increasing link number") judged as a trend.

In a design where every |dphi| is run at every N, the pooled least-squares slope of the per-run squared
residuals on N is the slope of the per-N mean squares (the RMS^2 the paper reports) on N: the whole
range at once, so no single noisy step decides it.  It rests on every run, not on the four per-N RMS
values, whose rank correlation can never exclude 0 at 95 % (4! = 24 orderings; at least 40 needed:
:func:`undulate.stats.rank_correlation_points`).  Design points, not runs, are the units of its
interval: a |dphi| has its own error at every N (the paired design), and the runs at +dphi and -dphi
are one pair mirrored.  Quick mode: 4 N x 9 dphi = 36 runs in 5 design points (t on 4), its first
look 3 (t on 2); full mode 17 (t on 16)."""

CONFINEMENT_TREND_RULE = (
    "the least-squares slope of the central state's width (lambda) against d/2A over the paper's range "
    "0.6-1.2 (every confinement there with a central state; at least 3), with its 95 % Student-t interval "
    "(the slope's standard error from linregress, n - 2 degrees of freedom): lower end above 0: holds; upper "
    "end at or below 0: fails; otherwise undecided (fewer than 3 widths: no result).  The paper gives no size "
    "of the broadening, so no band of no change is fixed from its words: a flat trend stays undecided, and a "
    "state closed throughout the range (slope 0 [0, 0]) fails")
"""The confinement claim ("increasing the confinement wall distance increased the range of final
longitudinal spacing ... the central compatibility state broadened") judged as a trend over the range the
paper states it on, d/2A in [0.6, 1.2], not step by step: no single narrower step decides it, and the
wider channels run beyond the range (where the walls stop holding the pair) do not enter it.  Each width
is a range of final offsets with no interval of its own; the scatter of the widths about the line is the
slope's uncertainty.  Quick mode: d/2A 0.6, 0.8, 1.0, 1.2 in the range (t on 2); full mode 0.6 to 1.2 in
0.1 (7 widths, t on 5), its first look 0.6, 0.8, 1.0, 1.2."""
