"""The contact impulse: on the default ground the pair escapes from dx = 0 within the window."""

from __future__ import annotations

import math

from ... import stats
from .._sensitivity_design import IMPULSE_DRAG_DEFAULT, impulse_case, impulse_drags
from ._protocol import CaseExplanation, CaseResults, Shown, all_of, negate, number, state_word

IMPULSE_EXPLAIN_DRAGS = (8.0, 16.0)
"""Drag levels (N s/m per link) at which the impulse claim must hold for the explanation to count as shown
(every level of the scan from 8 up: the trend, not one level)."""

CASES = tuple(impulse_case(c) for c in impulse_drags())


def judge(r: CaseResults) -> Shown:
    """Shown: the R^2 criterion fails at the default drag and holds at every drag in
    :data:`IMPULSE_EXPLAIN_DRAGS`, at each of which the pair escapes from dx = 0 more slowly; undecided
    while one of those R^2 criteria straddles (or has no interval)."""
    rows = {c: e for c in impulse_drags() if (e := r.get(impulse_case(c))) is not None}
    if IMPULSE_DRAG_DEFAULT not in rows or not all(c in rows for c in IMPULSE_EXPLAIN_DRAGS):
        return False, "no impulse runs at the default drag and at " + ", ".join(
            f"{c:g}" for c in IMPULSE_EXPLAIN_DRAGS) + " N s/m", None
    E = stats.Estimate.from_dict
    txt = "; ".join(f"drag {c:g} N s/m{' (default)' if e['default'] else ''}: R^2 {E(e['r2']):.2f} "
                    f"(linear: {state_word(e['linear'], e.get('linear_verdict'))}), "
                    f"first-period |dx| {e['first_period_dx_large_dphi']:.3f} lambda, phi0 max/min "
                    f"{e['phi0_spread_large_dphi']:.1f}" for c, e in sorted(rows.items()))
    txt += " (|dphi| >= pi/2; only the drag changed)"
    d = rows[IMPULSE_DRAG_DEFAULT]
    strong = [rows[c] for c in IMPULSE_EXPLAIN_DRAGS]
    escapes = [number(e["first_period_dx_large_dphi"]) for e in [d, *strong]]
    slower = (None if not all(math.isfinite(x) for x in escapes)
              else all(x < escapes[0] for x in escapes[1:]))
    shown = all_of(negate(d["linear"]), *(e["linear"] for e in strong), slower)
    return shown, txt, {"default": d["linear"], **{f"drag_{c:g}": rows[c]["linear"] for c in sorted(rows)},
                        "escape_slower": slower}


EXPLANATIONS = (
    CaseExplanation(
        study="potential", claim="the contact force over the first two periods grows linearly with |dphi|",
        cause="on the default ground (2 N s/m per link) contact pushes a detuned pair from dx = 0 most of the way "
              "to compatibility within the first period (overdamped: speed = force / drag), so the two-period "
              "impulse measures when the pair escapes, which depends on the common phase phi0, more than the "
              "detuning; with more linear drag (only that changed: 8 and 16 N s/m per link) the pair stays in "
              "contact over the window, the phi0 spread shrinks and the impulse grows linearly with |dphi|. "
              "The claim depends on a drag magnitude the paper does not give.",
        changes=(f"linear drag per link {IMPULSE_DRAG_DEFAULT:g} -> "
                 + " and ".join(f"{c:g}" for c in IMPULSE_EXPLAIN_DRAGS) + " N s/m",),
        cases=CASES, judge=judge),
)
