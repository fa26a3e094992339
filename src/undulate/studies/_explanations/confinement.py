"""Confinement: the reading of the paper's d, kept as a finding beside the claim (not an explanation).

The claim is judged with ``d`` the wall distance per swimmer (a pair's channel ``W = 2 d``,
:func:`undulate.theory.channel_width_m`), the reading under which the model's measured thresholds meet
the paper's statements about ``d/2A`` (docs/confinement_d.md).  The reading used before, ``d`` the
whole channel width, puts the paper's range 0.6-1.2 in channels of 63-125 mm, about the width below
which an in-phase pair is obstructed (101 mm) and narrower than the 2A + 2w a pair of bodies needs to
leave any band of neutral offsets, so the central state stays closed there.  That reading is one row of
the sensitivity study, judged here by the claim's unchanged criterion: a finding about what the claim
rests on, never a cause that turns a failing claim into ``explained``.
"""

from __future__ import annotations

import numpy as np

from .._criteria import WIDTH_TOL
from .._sensitivity_design import PAPER_RANGE_HIGH, PER_SWIMMER, WHOLE_WIDTH, confinement_case
from ._protocol import CaseFinding, CaseResults, Shown, all_of, negate, state_word

DEFAULT_READING = confinement_case(PER_SWIMMER)
WHOLE = confinement_case(WHOLE_WIDTH)


def _widths(e: dict) -> str:
    return ", ".join(f"{r:.2f} ({W * 1000:.0f} mm): {x:.3f}" for r, W, x in
                     zip(e["d_over_2A"], e["channel_width_m"], e["central_width_over_lambda"]))


def judge(r: CaseResults) -> Shown:
    """Shown: the claim's criterion holds with d per swimmer and fails with d the whole width, whose
    central state stays closed (width <= WIDTH_TOL) within d/2A <= 1.2.  The widths are point values (no
    intervals): undecided only where a broadening has no width to judge."""
    d, whole = r.get(DEFAULT_READING), r.get(WHOLE)
    if d is None or whole is None:
        return False, "no confinement runs under both readings of d", None
    bd, bw = d["broadens_centreline_A"], whole["broadens_centreline_A"]
    txt = (f"d per swimmer (default): widths at d/2A (W) {_widths(d)} "
           f"(broadens: {state_word(bd, 'no result' if bd is None else None)}); "
           f"d = whole width: {_widths(whole)} (broadens: {state_word(bw, 'no result' if bw is None else None)}; "
           f"bodies' model opens at d/2A = {whole['model_opening_d_over_2A']:.2f})")
    w = np.asarray(whole["central_width_over_lambda"], float)
    ratio = np.asarray(whole["d_over_2A"], float)
    closed = bool(np.all(w[ratio <= PAPER_RANGE_HIGH + 1e-9] <= WIDTH_TOL))
    shown = all_of(bd, negate(bw), closed)
    return shown, txt, {"whole_width_closed_in_range": closed, "per_swimmer_broadens": bd,
                        "whole_width_broadens": bw}


EXPLANATIONS = (
    CaseFinding(
        study="confinement",
        claim="the central (dx = 0) state broadens as the confinement d/2A grows (over 0.6-1.2)",
        cause="the claim rests on the reading of d: per swimmer (a pair's channel W = 2 d, the reading the "
              "measured obstruction and push-apart widths support) the central state opens within the paper's "
              "range; read as the whole channel width (W = d, 63-125 mm) the range lies where an in-phase pair "
              "is obstructed or its bodies leave no clearance W - 2A - 2w, and the state stays closed.",
        changes=("d read as the whole channel width (W = d) instead of the wall distance per swimmer (W = 2 d)",),
        cases=(DEFAULT_READING, WHOLE), judge=judge),
)
