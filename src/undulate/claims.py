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


def _packing(s: Summaries) -> list[Row]:
    p = _get(s, "packing") or {}
    phi, thr = p.get("phi_max_rad") or [], p.get("threshold_rho_tilde_mean") or []
    pairs = [(f, t) for f, t in zip(phi, thr) if _num(t) is not None]
    rho, rise = _num(p.get("spearman_threshold_vs_phi_max")), _num(
        p.get("largest_rise_of_threshold_between_neighbouring_phi_max"))
    falls = None if len(pairs) < 2 or rho is None or rise is None else (rho < 0 and rise <= 0)
    rel = _num(p.get("max_rel_diff_closed_form_vs_monte_carlo"))
    return [
        _row("the density at which swimmers start to collide falls as the phase spread grows "
             "(more phase spread needs more lateral room)",
             "as the phase variation increases the lateral spacing must increase or swimmers collide",
             "no result" if falls is None else
             "simulated threshold rho~ at phi_max = " + ", ".join(f"{f:.2f}: {t:.2f}" for f, t in pairs)
             + ("; above the densest grid point at phi_max = 0" if (p.get("threshold_above_grid") or [False])[0] else "")
             + (f"; {p.get('n_diverged')} of {p.get('n_runs')} runs diverged (left out; a threshold bracketing one is undefined)"
                if p.get("n_diverged") else "")
             + f"; Spearman {rho:+.2f} (holds if it falls: negative rank correlation, no rise between neighbours)",
             falls),
        _row("the closed form for the compatible density matches the Monte-Carlo estimate",
             "the expected value calculation agrees extremely well with the Monte-Carlo simulation",
             "no result" if rel is None else f"largest relative difference {rel:.2%} (holds if below 1%)",
             None if rel is None else rel < 0.01),
    ]


def _basins(s: Summaries) -> list[Row]:
    b = _get(s, "basins") or {}
    ret, away = b.get("n_returned"), b.get("n_pushed_away_from_zero")
    tp = _num(_get(b, "return_threshold", "positive", "threshold_dx0_over_lambda"))
    tn = _num(_get(b, "return_threshold", "negative", "threshold_dx0_over_lambda"))
    holds = None if ret is None or away is None else (ret > 0 and away > 0)
    return [_row(
        "dphi = 0 pairs return to dx = 0 from nearby starts and are pushed away from far ones",
        "starts close enough to zero evolve to dx_f = 0; beyond a threshold (withheld) they are pushed away",
        "no result" if holds is None else
        f"{ret} of {b.get('n_starts_dphi0')} starts returned, {away} were pushed away; return threshold "
        + (f"dx0/lambda = {tn:+.3f} / {tp:+.3f}" if tp is not None and tn is not None else "not bracketed")
        + " (holds if both behaviours occur)", holds)]


def _confinement(s: Summaries) -> list[Row]:
    c = _get(s, "confinement") or {}
    d, w = c.get("d_over_2A") or [], c.get("central_width_over_lambda") or []
    inside = _num(c.get("max_width_in_paper_range"))
    holds = None if inside is None else (inside > 0.01 and c.get("width_never_shrinks_with_d") is True)
    return [_row(
        "the central (dx = 0) state broadens as the confinement d/2A grows (over 0.6-1.2)",
        "increasing the wall distance increased the range of final spacings; the central state broadened",
        "no result" if holds is None else
        "width of the central state / lambda at d/2A = " + ", ".join(f"{a:.2f}: {x:.3f}" for a, x in zip(d, w))
        + " (holds if it never shrinks and exceeds 0.01 lambda within d/2A <= 1.2)", holds)]


def _potential(s: Summaries) -> list[Row]:
    p = _get(s, "potential") or {}
    r2 = _num(_get(p, "impulse_fit", "r2"))
    rows = [_row(
        "the contact force over the first two periods grows linearly with |dphi|",
        "cumulative contact forces over the first two periods are linearly dependent on dphi",
        "no result" if r2 is None else
        f"fit impulse = a|dphi| + b: a = {_get(p, 'impulse_fit', 'slope_Ns_per_rad'):.3g} N s/rad, "
        f"R^2 = {r2:.2f} (holds if R^2 >= 0.9)", None if r2 is None else r2 >= 0.9)]
    med = _num(p.get("median_fit_r2"))
    rows.append(_row(
        "dF against dx is linear (a harmonic well around compatibility)",
        "a linear relationship between the applied force and the steady separation",
        "no result" if med is None else f"median R^2 of the dF = k (dx - dx0) fits {med:.3f} (holds if >= 0.9)",
        None if med is None else med >= 0.9))
    per_beta = p.get("per_beta") or {}
    rho = {b: _num(v.get("spearman_k_vs_d")) for b, v in per_beta.items()}
    falls = None if not rho or any(r is None for r in rho.values()) else all(r < 0 for r in rho.values())
    rows.append(_row(
        "the cohesion stiffness k falls as the channel widens",
        "stiffness decreases with increasing wall width",
        "no result" if falls is None else
        "Spearman rank correlation of k with d per beta: " + ", ".join(f"{b} deg: {r:+.2f}" for b, r in rho.items())
        + " (holds if negative for every beta)", falls))
    a, m = _num(p.get("collapse_rms_log10k_vs_d_over_2A")), _num(p.get("collapse_rms_log10k_vs_d_m"))
    rows.append(_row(
        "stiffness curves for different amplitudes collapse when d is scaled by 2A",
        "when we normalise the wall width by gait amplitude the stiffness curves follow a similar trend",
        "no result" if a is None or m is None else
        f"scatter of log10 k about one curve: {a:.2f} decades against d/2A, {m:.2f} against d (holds if smaller)",
        None if a is None or m is None else a < m))
    return rows


def _swimming(s: Summaries) -> list[Row]:
    w = _get(s, "swimming") or {}
    v = _num(w.get("lone_swimmer_speed_m_s"))
    sv, ss = _get(w, "modes", "viscous", "slope"), _get(w, "modes", "swimming", "slope")
    rv, rs = _get(w, "modes", "viscous", "rms_residual_over_lambda"), _get(w, "modes", "swimming", "rms_residual_over_lambda")
    holds = None if None in (sv, ss, rv, rs) else (abs(ss - 1) < SLOPE_TOL and rs < RMS_TOL)
    return [_row(
        "swimming (anisotropic drag) pairs behave like non-swimming ones",
        "we found no qualitative difference in spatial dynamics between locomoting and non-locomoting simulations",
        "no result" if holds is None else
        f"lone swimmer {v * 1e3:.1f} mm/s head first; slope / RMS residual: swimming {ss:.2f} / {rs:.3f} lambda, "
        f"not swimming {sv:.2f} / {rv:.3f} lambda (holds if swimming pairs also follow the line: "
        f"|slope - 1| < {SLOPE_TOL}, RMS < {RMS_TOL} lambda)", holds)]


#: study name -> claim function (the report shows the rows under that study)
CLAIMS: dict[str, Callable[[Summaries], list[Row]]] = {
    "pairs": _pairs,
    "links": _links,
    "groups": _groups,
    "packing": _packing,
    "basins": _basins,
    "confinement": _confinement,
    "potential": _potential,
    "swimming": _swimming,
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
