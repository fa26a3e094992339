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
