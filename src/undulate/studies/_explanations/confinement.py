"""Confinement: bodies of width w leave a band of neutral offsets only above the paper's range of d/2A."""

from __future__ import annotations

import numpy as np

from .._criteria import WIDTH_TOL
from .._sensitivity_design import DEFAULT_BODY_M, PAPER_RANGE_HIGH, THIN_BODY_M, confinement_case
from ._protocol import CaseExplanation, CaseResults, Shown, all_of, negate, state_word

DEFAULT_WIDTH = confinement_case(DEFAULT_BODY_M)
THIN = confinement_case(THIN_BODY_M)


def _widths(e: dict) -> str:
    return ", ".join(f"{r:.2f}: {x:.3f}" for r, x in zip(e["d_over_2A"], e["central_width_over_lambda"]))


def judge(r: CaseResults) -> Shown:
    """Shown: with the default width the central state stays closed within d/2A <= 1.2, opens beyond the
    model's opening (which lies above 1.2), and with thin bodies (only w changed) it broadens in range.
    The widths are point values (no intervals): undecided only where a broadening has no width to judge."""
    d, thin = r.get(DEFAULT_WIDTH), r.get(THIN)
    if d is None or thin is None:
        return False, "no confinement runs at the default and the thin body width", None
    bd, bt = d["broadens_centreline_A"], thin["broadens_centreline_A"]
    txt = (f"default w: opens past d/2A = {d['model_opening_d_over_2A']:.2f} (model), widths {_widths(d)} "
           f"(broadens: {state_word(bd, 'no result' if bd is None else None)})"
           f"; w = {thin['body_width_m'] * 1000:g} mm (only w changed): widths {_widths(thin)} "
           f"(broadens: {state_word(bt, 'no result' if bt is None else None)})")
    w_d = np.asarray(d["central_width_over_lambda"], float)
    ratio = np.asarray(d["d_over_2A"], float)
    closed_in_range = bool(np.all(w_d[ratio <= PAPER_RANGE_HIGH + 1e-9] <= WIDTH_TOL))
    open_beyond = bool(np.any(w_d[ratio > d["model_opening_d_over_2A"]] > WIDTH_TOL))
    shown = all_of(negate(bd), closed_in_range, open_beyond, d["model_opening_d_over_2A"] > PAPER_RANGE_HIGH, bt)
    return shown, txt, {"default_closed_in_range": closed_in_range, "default_open_beyond_model": open_beyond,
                        "thin_broadens": thin["broadens_centreline_A"]}


EXPLANATIONS = (
    CaseExplanation(
        study="confinement",
        claim="the central (dx = 0) state broadens as the confinement d/2A grows (over 0.6-1.2)",
        cause="bodies of width w leave a band of neutral offsets only when the clearance d - 2A - 2w is positive, "
              "i.e. from d/2A = 1 + w/A, above the paper's range for our 15 mm links; with thin links (only w "
              "changed) the central state opens within d/2A <= 1.2.",
        changes=(f"link width w = {DEFAULT_BODY_M * 1000:g} -> {THIN_BODY_M * 1000:g} mm",),
        cases=(DEFAULT_WIDTH, THIN), judge=judge),
)
