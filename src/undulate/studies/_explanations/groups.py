"""Groups of three and four: in the groups' wide channels neighbours settle farther apart than pairs."""

from __future__ import annotations

import math

from ... import stats
from .._criteria import GROUP_CHANNEL_M, PAIR_CHANNEL_M
from .._sensitivity_design import group_case, spaced_channel_m
from ._protocol import CaseExplanation, CaseResults, Shown, all_of, negate, number, state_word

REFERENCE_PAIRS = group_case(2, PAIR_CHANNEL_M)

CAUSE = ("in the groups' channels (0.19 m for three, 0.22 m for four) neighbour centre lines settle farther "
         "apart than the reference pairs' in 0.13 m; at that spacing the band of offsets at which two bodies "
         "need not touch is wider, and neighbours stop at its near edge, short of the line; shown only if, "
         "with the channel narrowed so that neighbours have the pairs' spacing (0.13 m + 32 mm per extra "
         "swimmer; the same phases), the groups meet the claim's criterion.")


def cases(size: int) -> tuple:
    """The reference pairs, and groups of ``size`` in the groups study's channel and the spaced one."""
    return REFERENCE_PAIRS, group_case(size, GROUP_CHANNEL_M[size]), group_case(size, spaced_channel_m(size))


def _text(e: dict) -> str:
    E = stats.Estimate.from_dict
    return (f"d = {e['channel_width_m']:g} m: slope {E(e['slope']):.2f}, RMS {E(e['rms_residual_over_lambda']):.3f} "
            f"lambda, neighbour spacing {e['median_dy_m'] * 1000:.1f} mm, "
            f"{e['fraction_short_of_line'] * 100:.0f} % short of the line, "
            f"{e['fraction_inside_band'] * 100:.0f} % inside the contact-free band "
            f"(groups criterion: {state_word(e['follows_line_more_scatter'], e.get('follows_line_more_scatter_verdict'))})")


def judge(size: int, r: CaseResults) -> Shown:
    """Shown: groups of ``size`` fail the groups criterion in the groups study's channel with most
    neighbours short of the line, and meet it in the channel that gives them the pairs' spacing; undecided
    while either criterion straddles (or has no interval)."""
    ref, dflt, spaced = (r.get(c) for c in cases(size))
    if ref is None or dflt is None or spaced is None:
        return False, f"no groups of {size} in this plan", None
    E = stats.Estimate.from_dict
    measured = (f"{_text(dflt)}; {_text(spaced)} (same phases); pairs in 0.13 m: RMS "
                f"{E(ref['rms_residual_over_lambda']):.3f} lambda, spacing {ref['median_dy_m'] * 1000:.1f} mm")
    short = number(dflt["fraction_short_of_line"])
    shown = all_of(negate(dflt["follows_line_more_scatter"]), None if not math.isfinite(short) else short > 0.5,
                   spaced["follows_line_more_scatter"])
    return shown, measured, {"default": dflt["follows_line_more_scatter"],
                             "pairs_spacing": spaced["follows_line_more_scatter"],
                             "default_fraction_short": dflt["fraction_short_of_line"]}


def explanation(size: int) -> CaseExplanation:
    """The explanation of the groups study's claim for groups of ``size``."""
    def judge_size(r: CaseResults) -> Shown:
        return judge(size, r)

    return CaseExplanation(study="groups",
                           claim=f"groups of {size} follow the compatibility line with more scatter than pairs",
                           cause=CAUSE, changes=("the channel narrowed to give neighbours the pairs' spacing "
                                                 "(0.13 m + 32 mm per extra swimmer)",),
                           cases=cases(size), judge=judge_size)


EXPLANATIONS = (explanation(3), explanation(4))
