"""Swimming pairs: the swimming ground's weak linear drag leaves sliding undamped."""

from __future__ import annotations

import math

from ... import stats
from .._sensitivity_design import FLUID_DENSITIES, SWIM_DRAG_N_S_PER_M, SWIM_MIN_SPEED_M_S, CaseId, CaseSet
from ._protocol import CaseExplanation, CaseResults, Shown, all_of, negate, number, state_word

DEFAULT = CaseId.of(CaseSet.SWIM, fluid_density_kg_m3=FLUID_DENSITIES[0])
STRONG_DRAG = CaseId.of(CaseSet.SWIM, swim_drag_N_s_per_m=SWIM_DRAG_N_S_PER_M)


def judge(r: CaseResults) -> Shown:
    """Shown: the pairs criterion fails at the default and holds with only the linear drag raised, while
    the pairs still swim (the summary's ``swim_drag_pair_speed_m_s`` above :data:`SWIM_MIN_SPEED_M_S`);
    undecided while a criterion straddles (or the speed is missing)."""
    d, strong = r.get(DEFAULT), r.get(STRONG_DRAG)
    if d is None or strong is None:
        return False, "no swimming runs at the default or the stronger linear drag", None
    E = stats.Estimate.from_dict
    v = number(r.summary.get("swim_drag_pair_speed_m_s"))
    txt = "; ".join(f"{lab}: slope {E(e['slope']):.2f}, RMS {E(e['rms_residual_over_lambda']):.3f} lambda "
                    f"(criterion: {state_word(e['follows_line'], e.get('follows_line_verdict'))})"
                    for lab, e in (("linear drag 0.1 N s/m (default)", d),
                                   (f"{SWIM_DRAG_N_S_PER_M:g} N s/m (only the drag changed)", strong)))
    swims = None if not math.isfinite(v) else bool(v > SWIM_MIN_SPEED_M_S)
    txt += (f"; with {SWIM_DRAG_N_S_PER_M:g} N s/m the pairs " + ("swim at no measured speed" if swims is None else
            f"{'still swim' if swims else 'no longer swim'} at {v * 1000:.1f} mm/s"))
    shown = all_of(negate(d["follows_line"]), strong["follows_line"], swims)
    return shown, txt, {"default": d["follows_line"], "stronger_drag": strong["follows_line"], "speed_m_s": v}


EXPLANATIONS = (
    CaseExplanation(
        study="swimming", claim="swimming (anisotropic drag) pairs behave like non-swimming ones",
        cause="the swimming ground's weak linear drag (0.1 N s/m per link, a twentieth of the viscous ground's) "
              "leaves sliding along the body nearly undamped: pairs at large detuning are pushed through the "
              "compatible branch and end in single file; with 0.5 N s/m (only the drag changed; the pairs "
              "still swim) they follow the line. The claim depends on a drag magnitude the paper does not fix.",
        changes=(f"the swimming ground's linear drag per link -> {SWIM_DRAG_N_S_PER_M:g} N s/m",),
        cases=(DEFAULT, STRONG_DRAG), judge=judge),
)
