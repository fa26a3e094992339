"""Study ``sensitivity``: which claims hold under which of the model choices the paper leaves open.

One factor at a time, around the defaults.  The default-model rows that are
another study's runs (the groups study's three sweeps, the potential study's
impulse sweep) are those very runs, defined once in :mod:`._shared` and
reused by identity; every other case has its own runs.  Pair-type runs stop
by :data:`._runners.PAIR_STOP` (as the studies they vary do), except the
xi = 1 60 s runs that are cut short at 20 / 30 / 60 s, which run whole:

* **xi = 1 pairs** (the claim "pairs follow the compatibility line", the
  pairs study's criterion, 9 paper phases, 3-link pairs from dx0 = 0 in
  d = 0.13 m, as :mod:`.pairs` runs them): servo gain ``kp`` x 1/2, torque
  limit x 1/2, top speed (set-point slew limit) 6 -> 3 rad/s, contact time
  constant 2 dt -> 8 ms (softer), linear drag x 1/2 and x 2; run duration
  20 / 30 / 60 s and the steady window (mean of the last 1 / 3 / 5 periods),
  both from one 60 s run per phase cut short; the treatment of dphi = +-pi
  (the two compatible branches +-lambda/2 are equally near: nearest branch,
  the default, or the points left out).
* **xi = 3/2 pairs**: links per body N = 3 (the default, whose two joints
  move in exact antiphase: a standing wave, ``tests/test_wave_symmetry.py``)
  against N = 8 (joint phase steps 3 pi / 8: a travelling wave), only N
  changed (joint amplitude 45 degrees, the simulator's time step for N),
  30 s; N = 8 also up to 60 s (one run, stopped once steady, cut at 30 s).
* **links** (the claim "the error from compatibility falls as links are
  added"): a third joint-amplitude rule, ``equal-A``, in which the joint
  amplitude beta(N) is chosen so that the free N-link swimmer's body
  amplitude A equals the 3-link body's (secant iteration on free-swimmer
  runs), so d/2A is the same at every N (the links study's two rules change
  A and therefore the confinement).  With and without the dphi = +-pi points.
  The same runs judged against the line drawn with lambda_x, the bodies'
  wavelength along the channel (their head-to-tail extent, measured in the
  runs); and equal-A pairs (beta(N) from free swimmers with the guide) with
  the yaw recoil removed (:attr:`~undulate.params.Scene.heading_guide`, only
  that changed), judged with lambda = L and with lambda_x (``LINK_SETS``).
  The cause of the link-number failure counts as shown only when the last
  set alone meets the claim's criterion.
* **confinement** (the claim "the central state broadens over d/2A =
  0.6-1.2"): dphi = 0 pairs from dx0/lambda in {-0.15, 0, 0.15} (full: 5
  starts) for 40 s at d/2A = 0.9, 1.2 and the d at which the body's *edge*
  amplitude A + w/2 gives d/2(A + w/2) = 1.2, under the paper's reading of
  d (the wall distance per swimmer, a pair's channel W = 2 d: the default,
  docs/confinement_d.md) and, as one row, d read as the whole channel width
  (W = d, channels half as wide); the claim is judged with A the centre-line
  amplitude (default) and with A + w/2.  The compatibility model for bodies
  of width w has no band of neutral offsets until the clearance W - 2A - 2w
  is positive: from d/2A = (A + w)/2A per swimmer, (A + w)/A whole-width.

* **swimming** (the claim "swimming pairs behave like non-swimming ones",
  judged by the pairs criterion): the swimming ground's fluid density 1000
  (water, the default) and 250 kg/m^3 (a quarter of the anisotropic drag);
  its linear drag per link 0.1 N s/m (the default) and
  :data:`SWIM_DRAG_N_S_PER_M` (more damping of sliding; the pairs still swim).
* **groups** (the claims "groups of 3 / 4 follow the compatibility line with
  more scatter than pairs", the groups study's criterion against reference
  pairs in d = 0.13 m): the groups study's runs (three swimmers at phases
  ``(0, dphi, 2 dphi)`` in d = 0.19 m; four with random phases in 0.22 m;
  30 s; the groups study's plan: its phases and draws, and its reference
  pairs at the same phases) and the same runs (same phases, same draws) in
  the channel that gives neighbours the reference pairs' lateral spacing,
  ``d = 0.13 m + (n - 2) x`` :data:`PAIR_SPACING_M` (0.162 and 0.194 m).
* **potential** (the claim "the contact impulse over the first two periods
  grows linearly with |dphi|", R^2 lower bound >= 0.9): the impulse runs
  of the potential study (dx0 = 0, 6 s; its grid,
  :func:`._analysis.impulse_design`: 9 dphi x 4 common phases phi0 quick,
  37 x 8 full) fitted with and without dphi = +-pi, and the same runs with the viscous ground's linear
  drag per link 1, 4, 8 and 16 N s/m (default 2): with how fast the pair
  escapes from dx = 0 toward compatibility (the first period's mean |dx|
  is recorded) changes what the two-period window measures.

The summary's ``table`` has one row per (factor, level, claim): the verdict
by that claim's own criterion and its key number with the 95 % interval
(``holds``, ``fails`` when an interval lies wholly outside its region,
``undecided`` when one straddles a bound, ``no result`` only where a number
is missing; each entry's ``*_verdict`` beside its True / False / None).
``EXPLANATIONS`` state the causes of failing claims that these runs
demonstrate (:class:`~._protocol.Explanation`; :mod:`undulate.claims`
marks such a claim ``explained`` only when the check is true; None when a
condition it rests on is undecided): one module
per cause in :mod:`._explanations`, each reading the summary's results by
typed case id (:class:`~._sensitivity_design.CaseId`; every pair case's
entry, group case, reading of d and impulse drag carries its ``case_id``).
The constants, the plan and the case ids live in :mod:`._sensitivity_design`;
the dataset is assembled one factor group at a time (the ``_data_*`` steps of
:mod:`._sensitivity_runs`) and summarised the same way (the ``_summary_*`` steps
of :mod:`._sensitivity_summary`).

Each factor group is a part of the plan that the explanations reading its cases read
(:data:`~._sensitivity_design.FACTOR_GROUPS`, ``Explanation.reads``), and the staging engine hands the
study, for each, the plan it follows (:meth:`~._context.StudyContext.plan_for`): None when no needed
explanation reads it (the claim each explains holds, is undecided or has no result in the output folder,
so it cannot be ``explained``).  A skipped group keeps its variables and cases, filled with NaN, and runs
nothing; the dataset's ``skipped_factor_groups`` attribute (a JSON list) names it, the summary's
``skipped_factor_groups`` and ``skipped_cases`` carry it on, its table rows read ``no result``
(:data:`NOT_RUN`) and its explanations are not judged (shown None,
:data:`~._explanations._protocol.NOT_RUN`).  A group every needed explanation of which an earlier look
decided is handed that look's plan: its runs are reused, NaN at the dphi that look did not run.  The two
xi = 1 groups feed the table only and always run, on their own pair phases
(:attr:`~._sensitivity_design.Plan.xi1_dphi_rad`: full mode's third look keeps them on the 17 of the
second while the other groups still open run the cap's 33; NaN at the rest).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import xarray as xr

from ..errors import UndulateError
from . import _analysis as analysis
from ._criteria import PAIR_CHANNEL_M
from ._explanations import EXPLANATIONS
from ._context import StudyContext
from ._protocol import Study
from ._registry import register
from ._sensitivity_design import (  # noqa: F401 - the study's constants, re-exported
    BETA_DEG, CONFINEMENT_S, D_READING_SCALE, D_READINGS, DEFAULT_BODY_M, DEFAULT_S, DURATIONS_S, FACTOR_GROUPS,
    FLUID_DENSITIES, IMPULSE_DRAG_DEFAULT, IMPULSE_DRAGS_N_S_PER_M, LEFT_OUT, LONG_S, MODEL_DEFAULTS, MODEL_LEVELS,
    PAIR_SPACING_M, PAPER_RANGE_HIGH, PER_SWIMMER, SKIPPABLE_GROUPS, SWIM_DRAG_N_S_PER_M, SWIM_MIN_SPEED_M_S,
    WHOLE_WIDTH, WINDOWS, CaseId, CaseSet, Plan, confinement_case, group_case, group_cases, impulse_case,
    impulse_drags, pair_cases, plan, spaced_channel_m, xi32_durations)
from ._sensitivity_runs import (
    _case_variables, _data_confinement, _data_groups, _data_impulse, _data_links_equal_a, _data_links_guided,
    _data_swimming, _data_xi1_model, _data_xi1_windows, _data_xi32, _Runs)
from ._sensitivity_summary import (  # noqa: F401 - the summary's public names, re-exported
    CLAIM_LABELS, LINK_SETS, NOT_RUN, central_width, follows_line, line_checks, line_verdict, skipped_groups,
    summary)


def dataset(ctx: StudyContext, p: Plan) -> xr.Dataset:
    """The sensitivity runs, one factor group per ``_data_*`` step (side by side on the Warp backend:
    :meth:`StudyContext.together`), as one dataset; the pair cases along ``case`` in the order of
    :func:`~._sensitivity_design.pair_cases` (checked)."""
    dphis = np.asarray(p.dphi_rad, float)
    group_plans = {g: ctx.plan_for(g, p) for g in SKIPPABLE_GROUPS}  # None: not run
    skipped = frozenset(g for g, q in group_plans.items() if q is None)
    r = _Runs(ctx, p, dphis, float(ctx.lone_swimmer()["amplitude_m"]), skipped)

    def on(group: str) -> _Runs:
        q = group_plans[group]
        return r if q is None or q is p else r.on_plan(q)

    xi32, links, conf, groups, swim, imp = (on(g) for g in ("xi32", "links", "confinement", "groups", "swimming",
                                                           "impulse"))
    xi1 = r if p.xi1_dphi_rad is None else r.on_plan(dataclasses.replace(p, dphi_rad=p.xi1_phases))
    # the factor groups' runs do not depend on each other (side by side on the Warp backend)
    (model, windows, xi32_cases, equal_a, guided, (conf_data, conf_coords), (group_data, group_coords),
     (swim_cases, swim_data), (imp_data, imp_coords)) = ctx.together(
        lambda: _data_xi1_model(xi1), lambda: _data_xi1_windows(xi1), lambda: _data_xi32(xi32),
        lambda: _data_links_equal_a(links), lambda: _data_links_guided(links), lambda: _data_confinement(conf),
        lambda: _data_groups(groups), lambda: _data_swimming(swim), lambda: _data_impulse(imp))
    cases = (r.cases_on_axis(model + windows, xi1) + r.cases_on_axis(xi32_cases, xi32)
             + r.cases_on_axis(equal_a + guided, links))
    if swim is not r:  # its one variable along dphi
        dims, speed, attrs = swim_data["swim_drag_pair_speed"]
        swim_data = {"swim_drag_pair_speed": (dims, r.on_axis(speed, swim.dphis), attrs)}
    cases += r.cases_on_axis(swim_cases, swim)
    if [c.id for c in cases] != list(pair_cases(p)):
        raise UndulateError("the sensitivity dataset's cases differ from _sensitivity_design.pair_cases: "
                            + ", ".join(str(c.id) for c in cases))
    case_data, case_coords = _case_variables(cases, dphis)
    amp = {"amplitude_3_links": ((), r.A3, {"units": "m", "long_name": "free 3-link swimmer's A (default gait)"})}
    return xr.Dataset(
        {**case_data, **conf_data, **imp_data, **group_data, **swim_data, **amp},
        coords={**case_coords, **{k: v for k, v in conf_coords.items() if k != "time"}, **imp_coords,
                "time": conf_coords["time"], **group_coords},
        attrs={"title": "model sensitivity: claims against the model choices the paper leaves open",
               "channel_width_m": PAIR_CHANNEL_M, "n_dphi": len(dphis), "steady_rule": analysis.STEADY_RULE,
               "slope_method": analysis.SLOPE_METHOD,
               "skipped_factor_groups": json.dumps([g for g in SKIPPABLE_GROUPS if g in skipped])},
    )


def figure(ds: xr.Dataset):
    from ..plotting.sensitivity import plot_sensitivity

    return plot_sensitivity(ds, summary(ds))


def stages(quick: bool) -> tuple[Plan, ...]:
    """The plan in looks, in step with the studies whose runs it shares (groups, potential): the pair
    phases, the groups' phases and draws and the impulse grid thinned (:mod:`._stages`).  Full mode's
    pair phases 9, 17, 33 (the xi = 1 cases' 9, 17, 17: :data:`~._sensitivity_design.FULL_PAIR_REFINE`).
    Quick mode's 5 and 9 (the xi = 1 cases' 5 and 5), not one look of 5: a slope on
    5 mirrored dphi rests on 2 mirror pairs (:func:`undulate.stats.mirrored_line_fit`, 1 degree of
    freedom), too few to show an explanation's "follows the line"; the second look runs only the factor
    groups of the explanations still undecided (the others' parts keep the first look's plan)."""
    from ._sensitivity_design import thinned_plan
    from ._stages import strides

    if quick:  # the xi = 1 cases stay on their 5
        return tuple(thinned_plan(plan(True), k, k, 1) for k in strides(True))
    p = plan(False)
    return tuple(thinned_plan(p, k, k_dphi, k_xi1)
                 for k, k_dphi, k_xi1 in zip(strides(False), (4, 2, 1), (2, 1, 1)))


register(Study(
    name="sensitivity", plan=plan, stages=stages, dataset=dataset, summary=summary, claims=(), explanations=EXPLANATIONS,
    figure=figure,
    description="Model sensitivity: the xi = 1 and xi = 3/2 pair claims, the link-number trend and the "
                "confinement claim against servo, contact, drag, duration, steady rule, dphi = +-pi, links per "
                "body, the equal-A amplitude rule, the reading of d and the definition of A; groups against the "
                "neighbours' lateral spacing (one at a time)."))
