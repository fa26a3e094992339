"""The paper's qualitative claims (SPEC §4), each judged from a study's summary.

Every claim is a small pure function of the studies' JSON summaries
(``{study name: summary dict}``) that returns rows ``{"claim", "paper",
"measured", "holds"}`` (``holds`` is True, False or None when the study did
not produce what the claim needs).  The criteria are stated in the row's
``measured`` text; they were fixed before looking at full-mode results and
are deliberately loose: they ask whether the paper's *qualitative*
statement holds, not whether a withheld number is matched.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

__all__ = ["CLAIMS", "evaluate"]

Row = dict[str, Any]
Summaries = dict[str, dict[str, Any]]


def _get(d: Any, *keys: Any) -> Any:
    for k in keys:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


def _num(v: Any) -> float | None:
    return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else None


def _row(claim: str, paper: str, measured: str, holds: bool | None) -> Row:
    return {"claim": claim, "paper": paper, "measured": measured, "holds": holds}


SLOPE_TOL = 0.2  # |slope - 1| allowed for "follows the compatibility line"
RMS_TOL = 0.1  # RMS residual from the nearest branch, in wavelengths


def _pairs(s: Summaries) -> list[Row]:
    rows = []
    per = _get(s, "pairs", "per_xi") or {}
    for key, label in (("1", "1"), ("0.75", "3/4"), ("1.5", "3/2")):
        slope, rms = _num(_get(per, key, "slope")), _num(_get(per, key, "rms_residual_over_lambda"))
        n, steady = _get(per, key, "n_runs"), _get(per, key, "n_steady")
        holds = None if slope is None or rms is None else (abs(slope - 1) < SLOPE_TOL and rms < RMS_TOL)
        rows.append(_row(
            f"xi = {label}: contact drives pairs to a steady dx that follows the compatibility line",
            "steady dx is approximately linear in dphi and agrees with dx = lambda dphi / 2 pi",
            "no result" if holds is None else
            f"slope {slope:.3f}, RMS residual {rms:.3f} lambda, {steady}/{n} runs steady "
            f"(holds if |slope - 1| < {SLOPE_TOL} and RMS < {RMS_TOL} lambda)", holds))
    std0 = _num(_get(per, "0", "dx_std_m"))
    rms1 = _num(_get(per, "1", "rms_residual_m"))
    holds = None if std0 is None or rms1 is None else std0 > 3 * rms1
    rows.append(_row(
        "the standing wave (xi = 0) gives large scatter in dx",
        "with a stationary body wave the robots and simulation displayed large variance in dx",
        "no result" if holds is None else
        f"std of steady dx at xi = 0: {std0:.3f} m, against an RMS residual of {rms1:.3f} m at xi = 1 "
        "(holds if more than 3 times larger)", holds))
    return rows


def _links(s: Summaries) -> list[Row]:
    per_rule = _get(s, "links", "per_rule") or {}
    rows = []
    for rule, text in (("fixed", "joint amplitude 45 deg at every N"),
                       ("curvature", "joint amplitude 45 deg x 3/N")):
        per_n = _get(per_rule, rule, "per_n") or {}
        ns = sorted(per_n, key=int)
        rms = [_num(_get(per_n, n, "rms_residual_over_lambda")) for n in ns]
        if not ns or any(r is None for r in rms):
            rows.append(_row(f"error from compatibility falls as links are added ({text})",
                             "RMS error decreases with increasing link number", "no result", None))
            continue
        falls = all(b < a for a, b in zip(rms, rms[1:]))
        rows.append(_row(
            f"error from compatibility falls as links are added ({text})",
            "the RMS error between simulation and Eq. (2) decreased with increasing link number (values withheld)",
            "RMS residual / lambda for N = " + ", ".join(f"{n}: {r:.3f}" for n, r in zip(ns, rms))
            + " (holds if it decreases at every step)", falls))
    return rows


def _groups(s: Summaries) -> list[Row]:
    per = _get(s, "groups", "per_group_size") or {}
    rms_pair = _num(_get(s, "pairs", "per_xi", "1", "rms_residual_over_lambda"))
    rows = []
    for size in ("3", "4"):
        slope, rms = _num(_get(per, size, "slope")), _num(_get(per, size, "rms_residual_over_lambda"))
        if slope is None or rms is None:
            rows.append(_row(f"groups of {size} follow the compatibility line with more scatter than pairs",
                             "good agreement with compatibility; larger variation than in pairs", "no result", None))
            continue
        more = None if rms_pair is None else rms > rms_pair
        holds = abs(slope - 1) < SLOPE_TOL and rms < 2 * RMS_TOL and (more is not False)
        rows.append(_row(
            f"groups of {size} follow the compatibility line with more scatter than pairs",
            "nearest-neighbour dx agrees with compatibility; the variation is larger than in pair experiments",
            f"slope {slope:.3f}, RMS residual {rms:.3f} lambda"
            + ("" if rms_pair is None else f" vs {rms_pair:.3f} lambda for pairs at xi = 1")
            + f" (holds if |slope - 1| < {SLOPE_TOL}, RMS < {2 * RMS_TOL} lambda and above the pairs')",
            holds))
    return rows


#: study name -> claim function (the report shows the rows under that study)
CLAIMS: dict[str, Callable[[Summaries], list[Row]]] = {
    "pairs": _pairs,
    "links": _links,
    "groups": _groups,
}


def evaluate(name: str, summaries: Summaries) -> list[Row]:
    """Claims owned by study ``name``, judged from all available summaries.

    A study may also carry its own ``summary["claims"]`` rows; they are
    appended.
    """
    rows = CLAIMS[name](summaries) if name in CLAIMS else []
    own = _get(summaries, name, "claims")
    if isinstance(own, list):
        rows.extend(own)
    return rows
