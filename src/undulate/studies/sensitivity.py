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
demonstrate (:class:`~._registry.Explanation`; :mod:`undulate.claims`
marks such a claim ``explained`` only when the check is true; None when a
condition it rests on is undecided): one module
per cause in :mod:`._explanations`, each reading the summary's results by
typed case id (:class:`~._sensitivity_design.CaseId`; every pair case's
entry, group case, reading of d and impulse drag carries its ``case_id``).
The constants, the plan and the case ids live in :mod:`._sensitivity_design`;
the dataset is assembled one factor group at a time (the ``_data_*`` steps)
and summarised the same way (the ``_summary_*`` steps and
:func:`_groups_summary`).

Each factor group is a part of the plan that the explanations reading its cases read
(:data:`~._sensitivity_design.FACTOR_GROUPS`, ``Explanation.reads``), and the staging engine hands the
study, for each, the plan it follows (:meth:`~._registry.StudyContext.plan_for`): None when no needed
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
import functools
import json
import math
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
import xarray as xr

from .. import stats, theory
from ..errors import UndulateError
from ..observables import steady_state
from ..params import SwimmerGeometry
from ..sweep import Grid
from . import _analysis as C
from ._criteria import CENTRAL, LINE_RMS_TOL, LINE_SLOPE_TOL, PAIR_CHANNEL_M, R2_MIN, WIDTH_TOL
from ._explanations import EXPLANATIONS, results_by_case
from ._gaits import equal_amplitude_beta
from ._registry import FAILS, HOLDS, NO_RESULT, UNDECIDED, Study, StudyContext, register
from ._runners import BODY_LENGTH_M, PAIR_STOP, PERIOD_S, RECORD_HZ, group_point, pair_point
from ._sensitivity_design import (  # noqa: F401 - the study's constants, re-exported
    FACTOR_GROUPS, BETA_DEG, CONFINEMENT_S, DEFAULT_BODY_M, DEFAULT_S, DURATIONS_S, FLUID_DENSITIES, IMPULSE_DRAG_DEFAULT,
    IMPULSE_DRAGS_N_S_PER_M, LEFT_OUT, LONG_S, MODEL_DEFAULTS, MODEL_LEVELS, PAIR_SPACING_M, PAPER_RANGE_HIGH,
    SWIM_DRAG_N_S_PER_M, SWIM_MIN_SPEED_M_S, D_READING_SCALE, D_READINGS, PER_SWIMMER, WHOLE_WIDTH, WINDOWS,
    CaseId, CaseSet, Plan, confinement_case,
    group_case, group_cases, impulse_case, impulse_drags, pair_cases, plan, spaced_channel_m, xi32_durations)
from ._shared import group_part, group_sweep, impulse_sweep


SKIPPABLE_GROUPS: tuple[str, ...] = tuple(dict.fromkeys(FACTOR_GROUPS.values()))
"""The factor groups that run only for a needed explanation, in the order the dataset makes them."""

NOT_RUN = "not run (the claim it would explain does not fail)"
"""The table's reason for the rows of a skipped factor group (verdict ``no result``)."""


def _timestep(n_links: int) -> float:
    from ..params import Scene
    from ..scene import auto_timestep

    return auto_timestep(Scene(geometry=SwimmerGeometry(n_links=n_links)))


def _cut(run: xr.Dataset, duration_s: float) -> xr.Dataset:
    return run.sel(time=slice(None, duration_s + 1e-9))


def _pair_rows(run: xr.Dataset, dphi: float, lam: float, amp: float, windows=(3,)) -> dict[int, tuple]:
    """Final dx/lambda, residual/lambda and steady flag of one pair run per steady window."""
    rec, series = C.pair_record(run, dphi, lam, amp)
    out = {}
    for w in windows:
        if w == C.STEADY_WINDOW:
            out[w] = (rec["dx_steady"] / lam, rec["residual"] / lam, rec["steady"])
            continue
        da = xr.DataArray(series / lam, coords={"time": run["time"].values}, dims="time")
        st = steady_state(da, PERIOD_S, tol=C.STEADY_TOL, window=w)
        v = float(st["value"])
        out[w] = (v, float(theory.compatibility_residual(v, dphi, 1.0)), float(bool(st["steady"])))
    return out


# ------------------------------------------------------------------ dataset
def _pair_fn(duration_s: float, stop=PAIR_STOP):
    """The pair runner in the pairs study's channel (xi = 1 levels, the equal-A and guided link runs)."""
    return functools.partial(group_point, n_swimmers=2, channel_width_m=PAIR_CHANNEL_M, duration_s=duration_s,
                             stop=stop)


@dataclass
class _Case:
    """One pair case: its id, display labels and (dphi, 3) rows of final dx/lambda, residual, steady."""

    id: CaseId
    factor: str
    level: str
    default: bool
    rows: np.ndarray
    n_links: int
    beta: float
    amplitude: float
    xi: float
    wavelength: float


@dataclass(frozen=True)
class _Runs:
    """What every step of :func:`dataset` shares: the context, the plan, its dphi and the 3-link A."""

    ctx: StudyContext
    p: Plan
    dphis: np.ndarray
    A3: float
    skipped: frozenset[str] = frozenset()
    """The factor groups not run (no needed explanation reads them): their cases are NaN rows, made
    without a run."""

    @property
    def seed(self) -> int:
        return self.ctx.seed

    def on_plan(self, p: Plan) -> _Runs:
        """These runs on another look's plan ``p`` (a frozen group's)."""
        return dataclasses.replace(self, p=p, dphis=np.asarray(p.dphi_rad, float))

    def on_axis(self, values: np.ndarray, dphis: np.ndarray) -> np.ndarray:
        """``values`` (first axis: ``dphis``, a look's subset of this plan's dphi) on this plan's dphi axis,
        NaN at the dphi that look did not run."""
        out = np.full((len(self.dphis),) + np.shape(values)[1:], np.nan)
        out[C.positions(self.dphis, dphis)] = values
        return out

    def cases_on_axis(self, cases: list[_Case], sub: _Runs) -> list[_Case]:
        """The pair ``cases`` made by ``sub`` (a frozen group's runs) on this plan's dphi axis."""
        if sub is self:
            return cases
        return [dataclasses.replace(c, rows=self.on_axis(c.rows, sub.dphis)) for c in cases]

    def runs(self, group: str) -> bool:
        """Whether factor ``group`` runs (else its steps make NaN rows and call no sweep or lone swimmer)."""
        return group not in self.skipped

    def nan_rows(self) -> list[tuple]:
        return [(math.nan,) * 3] * len(self.dphis)

    def steady_rows(self, sweep, first: int, lam: float, amp: float, cut_s: float | None = None) -> list[tuple]:
        """The default steady rows of points ``first ..`` (one per dphi) of ``sweep``; NaN where a run failed."""
        rows = self.nan_rows()
        for j, d in enumerate(self.dphis):
            run = sweep.isel(point=first + j)
            if not bool(run["run_failed"]):
                rows[j] = _pair_rows(run if cut_s is None else _cut(run, cut_s), d, lam, amp)[3]
        return rows

    def pair_point_rows(self, runs) -> list[tuple]:
        """Final dx/lambda, residual and steady flag per dphi of ``pair_point`` runs (NaN where one failed)."""
        rows = self.nan_rows()
        for j, (d, run) in enumerate(zip(self.dphis, runs)):
            if not bool(run["run_failed"]):
                v = float(run["dx_final_over_lambda"])
                rows[j] = (v, float(theory.compatibility_residual(v, d, 1.0)), float(run["steady"]))
        return rows

    def case(self, cid: CaseId, factor: str, level: str, rows, default: bool = False, n_links: int = 3,
             beta: float = math.radians(BETA_DEG), amp: float | None = None, xi: float = 1.0,
             lam: float | None = None) -> _Case:
        return _Case(cid, factor, level, default, np.asarray(rows, float), n_links, beta,
                     self.A3 if amp is None else amp, xi, BODY_LENGTH_M / xi if lam is None else lam)

    def wavelength_x(self, sweep, first: int) -> float:
        """lambda_x: the head-to-tail extent along x (xi = 1: one wave) of both swimmers, mean over the
        runs ``first ..`` of ``sweep`` that have a result (NaN if none)."""
        ext = [float(sweep.isel(point=first + j)["extent_x"].mean()) for j in range(len(self.dphis))
               if not bool(sweep.isel(point=first + j)["run_failed"])]
        return float(np.mean(ext)) if ext else math.nan


def _data_xi1_model(r: _Runs) -> list[_Case]:
    """xi = 1, one model level changed at a time (30 s)."""
    pts = [{**MODEL_DEFAULTS, **over, "dphi_rad": float(d)} for _, _, over in MODEL_LEVELS for d in r.dphis]
    sim = r.ctx.sweep("xi1-model", _pair_fn(DEFAULT_S), Grid(points=pts, seed=r.seed)).isel(replicate=0)
    return [r.case(CaseId.of(CaseSet.XI1, **over), factor, level,
                   r.steady_rows(sim, k * len(r.dphis), BODY_LENGTH_M, r.A3))
            for k, (factor, level, over) in enumerate(MODEL_LEVELS)]


def _data_xi1_windows(r: _Runs) -> list[_Case]:
    """xi = 1 at the default model: run duration 20 / 30 / 60 s and the steady window, from one 60 s run
    per dphi cut short; the dphi = +-pi points left out."""
    fn60 = functools.partial(group_point, n_swimmers=2, channel_width_m=PAIR_CHANNEL_M, duration_s=LONG_S)
    base = r.ctx.sweep("xi1-default", fn60, Grid(axes={"dphi_rad": list(r.dphis)}, seed=r.seed)).isel(replicate=0)
    per_dur = {D: r.nan_rows() for D in DURATIONS_S}
    per_win = {w: r.nan_rows() for w in WINDOWS}
    for j, d in enumerate(r.dphis):
        run = base.isel(dphi_rad=j)
        if bool(run["run_failed"]):
            continue
        for D in DURATIONS_S:
            rows = _pair_rows(_cut(run, D), d, BODY_LENGTH_M, r.A3, windows=WINDOWS if D == DEFAULT_S else (3,))
            per_dur[D][j] = rows[3]
            if D == DEFAULT_S:
                for w in WINDOWS:
                    per_win[w][j] = rows[w]
    out = [r.case(CaseId.of(CaseSet.XI1, duration_s=D), "run duration",
                  f"{D:g} s" + (" (default)" if D == DEFAULT_S else ""), per_dur[D], default=D == DEFAULT_S)
           for D in DURATIONS_S]
    out += [r.case(CaseId.of(CaseSet.XI1, steady_window_periods=w), "steady-state rule",
                   f"final = mean of last {w} period(s) (default 3)", per_win[w])
            for w in WINDOWS if w != C.STEADY_WINDOW]
    out.append(r.case(CaseId.of(CaseSet.XI1, dphi_pi=LEFT_OUT), "dphi = +-pi", "left out (default: nearest branch)",
                      [row if abs(d) < np.pi - 1e-9 else (math.nan,) * 3
                       for row, d in zip(per_dur[DEFAULT_S], r.dphis)]))
    return out


def _data_xi32(r: _Runs) -> list[_Case]:
    """xi = 3/2: links per body N (30 s; N > 3 also 60 s: one run of up to 60 s, cut at 30 s).  Every run
    stops by :data:`PAIR_STOP` once steady, as the pairs study's and the N = 3 runs do: the rule's
    answer is the whole run's within the steady tolerance (its drift test carries the trend to the
    run's planned end, so a 60 s run stops no earlier than a 30 s one would), and a run steps on past
    30 s only while the rule finds the pair still drifting (``tests/test_stopping.py``)."""
    def pair_runs(n: int) -> tuple:  # (the pair runs, the free swimmer's A) of N links
        if not r.runs("xi32"):
            return None, math.nan
        fn = functools.partial(group_point, n_swimmers=2, channel_width_m=PAIR_CHANNEL_M,
                               duration_s=max(xi32_durations(n)), stop=PAIR_STOP)
        g = Grid(points=[{"waves_per_body": 1.5, "n_links": n, "timestep_s": _timestep(n),
                          "dphi_rad": float(d)} for d in r.dphis], seed=r.seed)
        return (r.ctx.sweep(f"xi32-N{n}", fn, g).isel(replicate=0),
                float(r.ctx.lone_swimmer(n_links=n, waves_per_body=1.5)["amplitude_m"]))

    out = []
    for n, (sw, amp) in zip(r.p.xi32_links, r.ctx.together(*(functools.partial(pair_runs, n) for n in r.p.xi32_links))):
        durations = xi32_durations(n)
        for D in durations:
            rows = r.nan_rows() if sw is None else r.steady_rows(sw, 0, BODY_LENGTH_M / 1.5, amp, cut_s=D)
            out.append(r.case(CaseId.of(CaseSet.XI32, n_links=n, duration_s=D), "links per body N at xi = 3/2",
                              f"N = {n}, {D:g} s" + (" (default)" if n == 3 else ""), rows, default=n == 3,
                              n_links=n, amp=amp, xi=1.5))
    return out


def _equal_a_gaits(r: _Runs, heading_guide: bool) -> list[tuple[int, float, float]]:
    """``(N, beta, A)`` per N of the plan: beta at which the free N-link swimmer (with its yaw recoil
    removed if ``heading_guide``) has the 3-link swimmer's A; the free 3-link body keeps its 45 deg.
    NaN beta and A (no run) when the links group is skipped."""
    if not r.runs("links"):
        return [(n, math.nan, math.nan) for n in r.p.links]
    def gait(n: int) -> tuple[int, float, float]:
        if n == 3 and not heading_guide:
            return n, math.radians(BETA_DEG), r.A3

        def amplitude_m(beta: float) -> float:
            return float(r.ctx.lone_swimmer(amplitude_rad=beta, n_links=n, waves_per_body=1.0,
                                            heading_guide=heading_guide)["amplitude_m"])

        return n, *equal_amplitude_beta(amplitude_m, n, r.A3)

    return r.ctx.together(*(functools.partial(gait, n) for n in r.p.links))  # one root search per N


def _link_cases(r: _Runs, sweep, gaits, sets: tuple[tuple[CaseSet, str, str], ...]) -> list[_Case]:
    """Per N of ``gaits``: the case judged with lambda = L and with lambda_x (``sets``: (case set,
    factor, level with ``{n}``) for each); NaN rows and lambda_x where ``sweep`` is None (not run)."""
    (free, f_free, l_free), (along_x, f_x, l_x) = sets
    out = []
    for i, (n, b, a) in enumerate(gaits):
        first = i * len(r.dphis)
        out.append(r.case(CaseId.of(free, n_links=n), f_free, l_free.format(n=n),
                          r.nan_rows() if sweep is None else r.steady_rows(sweep, first, BODY_LENGTH_M, a),
                          n_links=n, beta=b, amp=a))
        lx = math.nan if sweep is None else r.wavelength_x(sweep, first)
        out.append(r.case(CaseId.of(along_x, n_links=n), f_x, l_x.format(n=n),
                          r.nan_rows() if sweep is None else r.steady_rows(sweep, first, lx, a),
                          n_links=n, beta=b, amp=a, lam=lx))
    return out


def _link_sweep(r: _Runs, part: str, gaits, heading_guide: bool):
    """The equal-A pair runs of ``gaits``, one per (N, dphi); None (no run) when the links group is skipped."""
    if not r.runs("links"):
        return None
    extra = {"heading_guide": True} if heading_guide else {}
    pts = [{"n_links": n, "amplitude_rad": b, "timestep_s": _timestep(n), "waves_per_body": 1.0, **extra,
            "dphi_rad": float(d)} for n, b, _ in gaits for d in r.dphis]
    return r.ctx.sweep(part, _pair_fn(DEFAULT_S), Grid(points=pts, seed=r.seed)).isel(replicate=0)


def _data_links_equal_a(r: _Runs) -> list[_Case]:
    """links: the equal-A rule (A held at the 3-link value), lambda = L and lambda_x."""
    gaits = _equal_a_gaits(r, heading_guide=False)
    sw = _link_sweep(r, "links-equalA", gaits, heading_guide=False)
    return _link_cases(r, sw, gaits, (
        (CaseSet.LINKS, "joint-amplitude rule", "equal-A, N = {n}"),
        (CaseSet.LINKS_X, "wavelength of the compatibility line", "equal-A, lambda = lambda_x, N = {n}")))


def _data_links_guided(r: _Runs) -> list[_Case]:
    """links: the yaw recoil removed (Scene.heading_guide), A held at the 3-link value."""
    gaits = _equal_a_gaits(r, heading_guide=True)
    sw = _link_sweep(r, "links-guided", gaits, heading_guide=True)
    return _link_cases(r, sw, gaits, (
        (CaseSet.LINKS_GUIDED, "yaw recoil", "removed (heading guide), equal-A, N = {n}"),
        (CaseSet.LINKS_GUIDED_X, "yaw recoil and wavelength",
         "removed (heading guide), equal-A, lambda = lambda_x, N = {n}")))


def _data_confinement(r: _Runs) -> tuple[dict, dict]:
    """confinement: dphi = 0 pairs over d/2A (with the ratio at which the edge amplitude gives 1.2) under
    each reading of d (:data:`D_READINGS`: per swimmer, the default; the whole width, whose channel at
    the same d/2A is half as wide); (data variables, coordinates)."""
    w0 = DEFAULT_BODY_M
    r_edge = round(PAPER_RANGE_HIGH * (r.A3 + w0 / 2) / r.A3, 6)
    ratios = tuple(r.p.confinement_d_over_2A) + (r_edge,)
    starts = list(r.p.confinement_starts)
    if r.runs("confinement"):
        fnc = functools.partial(pair_point, duration_s=CONFINEMENT_S, amplitude_m=r.A3, stop=PAIR_STOP)
        finals, series_all = [], []
        for reading in D_READINGS:
            k = D_READING_SCALE[reading]
            gc = Grid(axes={"d_over_2A": [round(k * x, 10) for x in ratios], "dx0_over_lambda": starts}, seed=r.seed)
            part = "confinement" if reading == PER_SWIMMER else f"confinement-{reading}"
            conf = r.ctx.sweep(part, fnc, gc).isel(replicate=0)
            finals.append(np.where(conf["run_failed"].values, np.nan, conf["dx_final_over_lambda"].values))
            series_all.append(conf["dx_over_lambda"].values)
            time = conf["time"].values
        conf_final, series = np.stack(finals), np.stack(series_all)
    else:  # not run: NaN on the runs' axes (pair_point records at RECORD_HZ)
        time = np.round(np.arange(int(round(CONFINEMENT_S * RECORD_HZ)) + 1) / RECORD_HZ, 12)
        conf_final = np.full((len(D_READINGS), len(ratios), len(starts)), np.nan)
        series = np.full(conf_final.shape + (len(time),), np.nan)
    one = {"units": "1"}
    data = {
        "conf_dx_final_over_lambda": (("d_reading", "d_over_2A", "dx0"), conf_final, {
            **one, "long_name": "confinement runs: final dx/lambda (mean of the last 3 periods)"}),
        "conf_dx_over_lambda": (("d_reading", "d_over_2A", "dx0", "time"), series, {
            **one, "long_name": "confinement runs: dx/lambda over time"}),
    }
    coords = {
        "d_reading": ("d_reading", list(D_READINGS), {
            "long_name": "reading of the paper's d: wall distance per swimmer (W = 2 d, default) or whole width "
                         "(W = d)"}),
        "d_over_2A": ("d_over_2A", list(ratios), {**one, "long_name": "d over 2 A (centre-line A)"}),
        "dx0": ("dx0", starts, {**one, "long_name": "initial dx0/lambda"}),
        "time": ("time", time, {"units": "s"}),
    }
    return data, coords


_GROUP_FIELDS = {
    "dphi": ("group_dphi", "rad", "groups: neighbour phase difference phi_upper - phi_lower (NaN: padding)"),
    "dx_steady_over_lambda": ("group_dx_over_lambda", "1", "groups: steady neighbour offset dx / lambda"),
    "residual_over_lambda": ("group_residual_over_lambda", "1",
                             "groups: distance from the nearest compatibility branch / lambda"),
    "dy_steady": ("group_dy", "m", "groups: steady lateral spacing of the neighbours' centre lines"),
    "band_excess": ("group_band_excess", "m", "groups: distance outside the full compatibility band (0 = inside)"),
    "run": ("group_run", "1", "groups: the case's run of the neighbour pair (0, 1, ...; NaN: padding)"),
}
"""Group record field -> (data variable, units, long name)."""


def _data_groups(r: _Runs) -> tuple[dict, dict]:
    """groups: lateral spacing of neighbours (the same phases and draws in two channels; the groups study's
    own runs where the channel is its own); (data variables, coordinates) per neighbour pair (all NaN when
    the groups group is skipped)."""
    gdphis = list(r.p.group_dphi_rad)

    def group_runs(n: int, w: float) -> list[xr.Dataset]:
        if not r.runs("groups"):
            return []
        fn, grid = group_sweep(n, gdphis, r.p.group_draws, r.seed, channel_width_m=w)
        shared = w == {2: PAIR_CHANNEL_M, **C.GROUP_CHANNEL_M}[n]  # the groups study's own runs
        sw = (r.ctx.shared_sweep if shared else r.ctx.sweep)(group_part(n, w), fn, grid)
        return [run for run in C.sweep_runs(sw) if run is not None]

    cases = group_cases()  # the groups study's grid: the same per-run seeds, hence the same phase draws
    runs = r.ctx.together(*(functools.partial(group_runs, n, w) for n, w, _ in cases))
    recs = [[{**rec, "run": i} for i, run in enumerate(rs)
             for rec in C.group_records(C.trajectory(run, BODY_LENGTH_M), r.A3)] for rs in runs]
    n_nb = max(1, max(len(x) for x in recs))
    if not r.runs("groups"):  # not run: as many neighbour pairs as the runs would give (n - 1 per run)
        n_nb = max((n - 1) * group_sweep(n, gdphis, r.p.group_draws, r.seed, channel_width_m=w)[1].n_runs
                   for n, w, _ in cases)
    values = {f: np.full((len(cases), n_nb), np.nan) for f in _GROUP_FIELDS}
    for i, rows in enumerate(recs):
        for k, rec in enumerate(rows):
            for f in _GROUP_FIELDS:
                values[f][i, k] = rec[f]
    data = {var: (("group_case", "neighbour"), values[f], {"units": units, "long_name": name})
            for f, (var, units, name) in _GROUP_FIELDS.items()}
    coords = {
        "group_size": ("group_case", [c[0] for c in cases], {"units": "1", "long_name": "swimmers"}),
        "group_channel_width": ("group_case", [c[1] for c in cases], {"units": "m", "long_name": "d"}),
        "group_default": ("group_case", [c[2] for c in cases], {
            "long_name": "the groups study's channel (2: the reference pairs)"}),
    }
    return data, coords


def _data_swimming(r: _Runs) -> tuple[list[_Case], dict]:
    """swimming: strength of the anisotropic drag (fluid density) and the linear drag; (cases, the
    pairs' speed at the stronger linear drag); NaN rows when the swimming group is skipped."""
    if not r.runs("swimming"):
        return _swimming_cases(r, [r.nan_rows()] * len(FLUID_DENSITIES), r.nan_rows(), np.full(len(r.dphis), np.nan))
    fns = functools.partial(pair_point, duration_s=DEFAULT_S, stop=PAIR_STOP)
    gs = Grid(axes={"ground": ["swimming"], "fluid_density_kg_m3": list(FLUID_DENSITIES), "dphi_rad": list(r.dphis)},
              seed=r.seed)
    gsd = Grid(points=[{"ground": "swimming", "swim_drag_N_s_per_m": SWIM_DRAG_N_S_PER_M, "dphi_rad": float(d)}
                       for d in r.dphis], seed=r.seed)
    swim, swd = r.ctx.together(lambda: r.ctx.sweep("swimming", fns, gs).isel(replicate=0, ground=0),
                               lambda: r.ctx.sweep("swimming-drag", fns, gsd).isel(replicate=0))
    by_density = [r.pair_point_rows([swim.isel(fluid_density_kg_m3=k, dphi_rad=j) for j in range(len(r.dphis))])
                  for k in range(len(FLUID_DENSITIES))]
    speed = np.where(swd["run_failed"].values, np.nan, swd["speed_m_s"].values)
    return _swimming_cases(r, by_density, r.pair_point_rows([swd.isel(point=j) for j in range(len(r.dphis))]),
                           speed)


def _swimming_cases(r: _Runs, by_density, drag_rows, speed) -> tuple[list[_Case], dict]:
    """The swimming cases from their rows (per fluid density; at the stronger linear drag) and the pairs'
    speed at the stronger drag."""
    out = [r.case(CaseId.of(CaseSet.SWIM, fluid_density_kg_m3=rho), "anisotropic drag (swimming ground)",
                  f"fluid density {rho:g} kg/m^3" + (" (default)" if k == 0 else ""), rows, default=k == 0)
           for k, (rho, rows) in enumerate(zip(FLUID_DENSITIES, by_density))]
    out.append(r.case(CaseId.of(CaseSet.SWIM, swim_drag_N_s_per_m=SWIM_DRAG_N_S_PER_M),
                      "linear drag of the swimming ground", f"{SWIM_DRAG_N_S_PER_M:g} N s/m per link (default 0.1)",
                      drag_rows))
    return out, {"swim_drag_pair_speed": (("dphi",), speed, {
        "units": "m/s", "long_name": f"swimming pairs with {SWIM_DRAG_N_S_PER_M:g} N s/m linear drag: speed "
                                    "toward -x over the last 3 periods"})}


def _data_impulse(r: _Runs) -> tuple[dict, dict]:
    """potential: the contact impulse over the first two periods (the potential study's runs) and the same
    runs per linear drag of the ground; (data variables, coordinates)."""
    idphis, iphi0 = list(r.p.impulse_dphi_rad), list(r.p.impulse_phi0_rad)
    drags = list(impulse_drags())
    imp_by_drag = np.full((len(drags), len(idphis), len(iphi0)), np.nan)
    escape_by_drag = np.full_like(imp_by_drag, np.nan)
    impulse = np.full(len(idphis), np.nan)
    if r.runs("impulse"):
        imp, impd = r.ctx.together(
            lambda: r.ctx.shared_sweep("impulse", *impulse_sweep(idphis, iphi0, r.seed)).isel(replicate=0),
            lambda: r.ctx.sweep("impulse-drag", *impulse_sweep(idphis, iphi0, r.seed,
                                                              drag_N_s_per_m=IMPULSE_DRAGS_N_S_PER_M)).isel(replicate=0))
        impulse = np.nanmean(np.where(imp["run_failed"].values, np.nan, imp["impulse_2T_Ns"].values), axis=1)
    for k, c in enumerate(drags if r.runs("impulse") else ()):
        run = imp if c == IMPULSE_DRAG_DEFAULT else impd.isel(drag_N_s_per_m=IMPULSE_DRAGS_N_S_PER_M.index(c))
        bad = run["run_failed"].values
        imp_by_drag[k] = np.where(bad, np.nan, run["impulse_2T_Ns"].values)
        escape_by_drag[k] = np.where(bad, np.nan, np.abs(run["dx_period_over_lambda"].isel(period_time=0).values))
    data = {
        "impulse": ("impulse_dphi", impulse, {"units": "N s", "long_name": "pair contact impulse over the first "
                                                                   "2 periods from dx0 = 0, mean over phi0"}),
        "impulse_drag_all": (("impulse_drag", "impulse_dphi", "phi0"), imp_by_drag, {
            "units": "N s", "long_name": "pair contact impulse over the first 2 periods from dx0 = 0, per "
                                         "linear drag of the viscous ground"}),
        "impulse_drag_escape": (("impulse_drag", "impulse_dphi", "phi0"), escape_by_drag, {
            "units": "1", "long_name": "|dx| / lambda, mean over the first period (how far the pair has moved "
                                       "from dx0 = 0 toward compatibility)"}),
    }
    coords = {
        "impulse_drag": ("impulse_drag", drags, {"units": "N s/m", "long_name": "linear drag per link of the "
                                                                              "viscous ground (impulse runs)"}),
        "impulse_dphi": ("impulse_dphi", idphis, {"units": "rad", "long_name": "phase difference of the "
                                                                "impulse runs (the potential study's grid)"}),
        "phi0": ("phi0", iphi0, {"units": "rad", "long_name": "phase of swimmer 0 (impulse runs)"}),
    }
    return data, coords


def _case_variables(cases: list[_Case], dphis: np.ndarray) -> tuple[dict, dict]:
    """The pair cases as data variables and coordinates along ``case`` (and ``dphi``)."""
    one = {"units": "1"}
    rows = np.stack([c.rows for c in cases])
    data = {
        "dx_final_over_lambda": (("case", "dphi"), rows[:, :, 0], {
            **one, "long_name": "final dx/lambda (x_1 - x_0; mean of the case's steady window)"}),
        "residual_over_lambda": (("case", "dphi"), rows[:, :, 1], {
            **one, "long_name": "distance from the nearest compatibility branch / lambda"}),
        "steady": (("case", "dphi"), rows[:, :, 2] == 1.0, {
            "long_name": "steady by observables.steady_state (tol 0.01 lambda)"}),
        "n_links": ("case", [c.n_links for c in cases], {"units": "1"}),
        "joint_amplitude": ("case", [c.beta for c in cases], {"units": "rad"}),
        "amplitude": ("case", [c.amplitude for c in cases], {
            "units": "m", "long_name": "free swimmer's body amplitude A"}),
        "waves_per_body": ("case", [c.xi for c in cases], {"units": "1"}),
        "wavelength": ("case", [c.wavelength for c in cases], {
            "units": "m", "long_name": "lambda of the case's compatibility line (L / xi, or lambda_x: the "
                                      "bodies' head-to-tail extent along x per wave, measured in the runs)"}),
        "is_default": ("case", [c.default for c in cases]),
    }
    coords = {
        "case": ("case", np.arange(len(cases)), {"units": "1", "long_name": "case index"}),
        "case_id": ("case", [str(c.id) for c in cases], {"long_name": "typed case id (CaseId, text form)"}),
        "claim": ("case", [c.id.case_set.value for c in cases]),
        "factor": ("case", [c.factor for c in cases]),
        "level": ("case", [c.level for c in cases]),
        "dphi": ("dphi", dphis, {"units": "rad", "long_name": "phase difference phi_1 - phi_0"}),
    }
    return data, coords


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
               "channel_width_m": PAIR_CHANNEL_M, "n_dphi": len(dphis), "steady_rule": C.STEADY_RULE,
               "slope_method": C.SLOPE_METHOD,
               "skipped_factor_groups": json.dumps([g for g in SKIPPABLE_GROUPS if g in skipped])},
    )


# ------------------------------------------------------------------ summary
def _line(y, dphi) -> dict[str, Any]:
    fit = C.compatibility_fit(y, dphi)
    res = theory.compatibility_residual(np.asarray(y, float), np.asarray(dphi, float), 1.0)
    return {"slope": fit.slope, "rms": C.rms(res, dphi)}


def line_checks(slope: stats.Estimate, rms: stats.Estimate) -> list[stats.Check]:
    """The pairs study's criterion as :class:`~undulate.stats.Check` s: the slope's interval within
    1 +- LINE_SLOPE_TOL, the RMS residual's below LINE_RMS_TOL lambda."""
    return C.line_checks(slope, rms)


def follows_line(slope: stats.Estimate, rms: stats.Estimate) -> bool | None:
    """The pairs study's criterion on the intervals: True when both lie inside their regions, False when
    one lies wholly outside, None when one straddles a bound -- or when one has no interval
    (:func:`line_verdict` tells the two apart, as the pairs study does)."""
    if not (slope.has_interval and rms.has_interval):
        return None
    return stats.decide(line_checks(slope, rms))


def line_verdict(slope: stats.Estimate, rms: stats.Estimate) -> str:
    """:func:`follows_line` as a verdict: ``no result`` without both intervals, else holds / fails /
    undecided."""
    return _verdict(follows_line(slope, rms), missing=not (slope.has_interval and rms.has_interval))


LINK_SETS = {
    "links": "equal-A, lambda = L",
    "links-x": "equal-A, lambda = lambda_x",
    "links-guided": "equal-A, yaw recoil removed, lambda = L",
    "links-guided-x": "equal-A, yaw recoil removed, lambda = lambda_x",
}
"""The link-number sets (:class:`~._sensitivity_design.CaseSet` value -> label): A held at the 3-link
value at every N; the compatibility line drawn with lambda = L (the links study's) or with lambda_x, the
wavelength along the channel measured in the runs; the free body, or the body whose yaw recoil a heading
guide removes (only that changed)."""

CLAIM_LABELS = {"xi1": "xi = 1 pairs follow the line", "xi32": "xi = 3/2 pairs follow the line",
                "swim": "swimming pairs follow the line"}


def _verdict(ok: bool | None, missing: bool) -> str:
    """A table verdict: ``no result`` only where a number (an interval) is ``missing``; else ``ok`` True
    holds, False fails, None undecided (an interval straddles a bound of its region)."""
    if missing:
        return NO_RESULT
    return HOLDS if ok is True else FAILS if ok is False else UNDECIDED


def central_width(dx_final) -> float:
    xf = np.asarray(dx_final, float)
    c = np.isfinite(xf) & (np.abs(xf) < CENTRAL)
    return float(xf[c].max() - xf[c].min()) if c.any() else math.nan


def _broadens(ratios, widths, high=PAPER_RANGE_HIGH) -> bool | None:
    r, w = np.asarray(ratios, float), np.asarray(widths, float)
    ok = np.isfinite(w)
    inside = ok & (r <= high + 1e-6)
    if not inside.any():
        return None
    grows = bool(np.all(np.diff(w[ok]) >= -WIDTH_TOL))
    return bool(np.nanmax(w[inside]) > WIDTH_TOL and grows)


def _summary_cases(ds: xr.Dataset, skipped: frozenset[str] = frozenset()) -> tuple[dict[str, dict], list[dict]]:
    """Per pair case (keyed by its display label): its ``case_id``, the line fit and the pairs verdict;
    the table rows of the cases judged by the pairs criterion (not the link sets; ``no result``, not run,
    for a case of a ``skipped`` factor group)."""
    dphi = ds["dphi"].values
    open_ = np.abs(dphi) < np.pi - 1e-9
    table, cases = [], {}
    for i in range(ds.sizes["case"]):
        c = ds.isel(case=i)
        cid = CaseId.parse(str(c["case_id"].values))
        claim, factor, level = str(c["claim"].values), str(c["factor"].values), str(c["level"].values)
        y = c["dx_final_over_lambda"].values
        fit = _line(y, dphi)
        entry = {"case_id": str(cid), "claim": claim, "factor": factor, "level": level,
                 "default": bool(c["is_default"]), "n_links": int(c["n_links"]),
                 "joint_amplitude_deg": math.degrees(float(c["joint_amplitude"])),
                 "amplitude_m": float(c["amplitude"]), "wavelength_m": float(c["wavelength"]),
                 "slope": fit["slope"].to_dict(),
                 "rms_residual_over_lambda": fit["rms"].to_dict(),
                 "rms_residual_over_lambda_open_interval": C.rms(c["residual_over_lambda"].values[open_],
                                                                 dphi[open_]).to_dict(),
                 "n_runs": int(np.isfinite(y).sum()), "n_steady": int(c["steady"].values.sum()),
                 "follows_line": follows_line(fit["slope"], fit["rms"]),
                 "follows_line_verdict": line_verdict(fit["slope"], fit["rms"])}
        cases[f"{claim}: {factor}: {level}"] = entry
        if cid.case_set.value not in LINK_SETS:
            table += _not_run([{"claim": CLAIM_LABELS[claim], "factor": factor, "level": level,
                                "verdict": entry["follows_line_verdict"],
                                "key number": f"slope {fit['slope']:.2f}, RMS {fit['rms']:.3f} lambda, "
                                              f"{entry['n_steady']}/{entry['n_runs']} steady"}],
                              FACTOR_GROUPS.get(cid.case_set) in skipped)
    return cases, table


def _not_run(rows: list[dict], skipped: bool) -> list[dict]:
    """Table ``rows`` as they stand, or, for a ``skipped`` factor group, with verdict ``no result`` and
    the reason :data:`NOT_RUN` (in ``key number`` and ``reason``)."""
    if not skipped:
        return rows
    return [{**t, "verdict": NO_RESULT, "key number": NOT_RUN, "reason": NOT_RUN} for t in rows]


def skipped_groups(ds: xr.Dataset) -> frozenset[str]:
    """The factor groups the dataset did not run (its ``skipped_factor_groups`` attribute; none if absent)."""
    return frozenset(json.loads(ds.attrs.get("skipped_factor_groups") or "[]"))


def _summary_link_sets(cases: dict[str, dict]) -> tuple[dict[str, dict], list[dict]]:
    """The links study's criterion on each set of N (equal-A rule; lambda = L or lambda_x; recoil or not)."""
    link_sets, table = {}, []
    for claim, label in LINK_SETS.items():
        links = sorted((e for e in cases.values() if CaseId.parse(e["case_id"]).case_set.value == claim),
                       key=lambda e: e["n_links"])
        if not links:
            continue
        rms = [stats.Estimate.from_dict(e["rms_residual_over_lambda"]) for e in links]
        rms_open = [stats.Estimate.from_dict(e["rms_residual_over_lambda_open_interval"]) for e in links]
        out = {"label": label, "n_links": [e["n_links"] for e in links],
               "joint_amplitude_deg": [e["joint_amplitude_deg"] for e in links],
               "amplitude_m": [e["amplitude_m"] for e in links],
               "wavelength_over_L": [e["wavelength_m"] / BODY_LENGTH_M for e in links],
               "rms_residual_over_lambda": [r.to_dict() for r in rms],
               "rms_residual_over_lambda_open_interval": [r.to_dict() for r in rms_open],
               "falls": C.falls_with_links(rms), "falls_open_interval": C.falls_with_links(rms_open)}
        out["falls_verdict"] = _verdict(out["falls"], missing=_no_trend(rms))
        out["falls_open_interval_verdict"] = _verdict(out["falls_open_interval"], missing=_no_trend(rms_open))
        link_sets[claim] = out
        rows = (((label + " (all dphi)"), rms, out["falls_verdict"]),) + (
            ((label + ", dphi = +-pi left out"), rms_open, out["falls_open_interval_verdict"]),) * (claim == "links")
        for lab, seq, verdict in rows:
            table.append({"claim": "error falls as links are added", "factor": links[0]["factor"],
                          "level": lab, "verdict": verdict,
                          "key number": "RMS / lambda at N = " + ", ".join(
                              f"{e['n_links']}: {r:.4f}" for e, r in zip(links, seq))
                          + ("" if claim in ("links", "links-guided") else "; lambda_x / L " + ", ".join(
                              f"{e['wavelength_m'] / BODY_LENGTH_M:.3f}" for e in links))})
    return link_sets, table


def _no_trend(rms_by_n) -> bool:
    """No link-number trend can be judged: fewer than two N, or an RMS without an interval."""
    seq = list(rms_by_n)
    return len(seq) < 2 or not all(r.has_interval for r in seq)


def _linear(idphi, impulse) -> tuple[stats.LineFit, bool | None, str]:
    """The potential study's criterion: the impulse's line fit against |dphi|, whether it is linear (the
    R^2 interval above R2_MIN and the slope's above 0: True, False when one lies wholly outside, None when
    one straddles or has no interval) and the verdict (``no result`` only without the intervals)."""
    u, pooled = C.by_abs_dphi(idphi, impulse)  # +-dphi: one design point (C.by_abs_dphi)
    f = stats.line_fit(u, C.row_means(pooled))
    missing = not (f.r2.has_interval and f.slope.has_interval)
    ok = None if missing else stats.decide([f.r2.above(R2_MIN, "R^2"), f.slope.above(0.0, "slope")])
    return f, ok, _verdict(ok, missing)


def _summary_impulse(ds: xr.Dataset) -> tuple[dict[str, Any], list[dict]]:
    """potential: impulse linear in |dphi| (on the potential study's grid) with and without dphi = +-pi,
    and per linear drag of the ground (``by_drag``, each row with its ``case_id``)."""
    imp, idphi = ds["impulse"].values, ds["impulse_dphi"].values
    pot, table = {}, []
    for label, use in (("all dphi (default)", np.ones(idphi.shape, bool)),
                       ("dphi = +-pi left out", np.abs(idphi) < np.pi - 1e-9)):
        f, ok, verdict = _linear(idphi[use], imp[use])
        pot[label] = {"slope_Ns_per_rad": f.slope.to_dict(), "r2": f.r2.to_dict(), "linear": ok,
                      "linear_verdict": verdict}
        table.append({"claim": "impulse over 2 periods linear in |dphi|", "factor": "dphi = +-pi",
                      "level": label, "verdict": verdict,
                      "key number": f"a = {f.slope:.3g} N s/rad, R^2 = {f.r2:.2f}"})
    pot_drag = []
    if "impulse_drag" in ds.sizes:
        big = np.abs(idphi) >= np.pi / 2 - 1e-9
        for k, c in enumerate(ds["impulse_drag"].values):
            allv = ds["impulse_drag_all"].values[k]
            with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN rows: failed or not run (NaN)
                f, ok, verdict = _linear(idphi, C.row_means(allv))
                spread = float(np.nanmedian((np.nanmax(allv, 1) / np.nanmin(allv, 1))[big]))
                esc = float(np.nanmean(ds["impulse_drag_escape"].values[k][big]))
            pot_drag.append({"case_id": str(impulse_case(float(c))), "drag_N_s_per_m": float(c),
                             "default": bool(c == IMPULSE_DRAG_DEFAULT),
                             "slope_Ns_per_rad": f.slope.to_dict(), "r2": f.r2.to_dict(), "linear": ok,
                             "linear_verdict": verdict,
                             "phi0_spread_large_dphi": spread, "first_period_dx_large_dphi": esc})
            table.append({"claim": "impulse over 2 periods linear in |dphi|", "factor": "drag (impulse runs)",
                          "level": f"{c:g} N s/m per link" + (" (default)" if c == IMPULSE_DRAG_DEFAULT else ""),
                          "verdict": verdict,
                          "key number": f"R^2 = {f.r2:.2f}; |dphi| >= pi/2: first-period |dx| {esc:.3f} lambda, "
                                        f"phi0 max/min {spread:.1f}"})
    pot["by_drag"] = pot_drag
    return pot, table


def _summary_confinement(ds: xr.Dataset) -> tuple[dict[str, dict], list[dict]]:
    """confinement: per reading of d (keyed by :data:`D_READINGS`, each with its ``case_id``) the channel
    widths, the central state's width over d/2A and whether it broadens, by centre-line A and by edge
    amplitude A + w/2; the bodies' model opens where the clearance W - 2A - 2w turns positive."""
    A = float(ds["amplitude_3_links"])
    ratios = ds["d_over_2A"].values
    w = DEFAULT_BODY_M
    conf = {}
    for ri, reading in enumerate(ds["d_reading"].values):
        reading = str(reading)
        k = D_READING_SCALE[reading]
        widths = [central_width(ds["conf_dx_final_over_lambda"].values[ri, j]) for j in range(len(ratios))]
        r_edge = ratios * A / (A + w / 2)
        conf[reading] = {
            "case_id": str(confinement_case(reading)), "d_reading": reading, "body_width_m": w,
            "d_over_2A": ratios, "d_over_2A_edge": r_edge,
            "channel_width_m": 2 * k * ratios * 2 * A,
            "central_width_over_lambda": np.asarray(widths),
            "model_opening_d_over_2A": (2 * A + 2 * w) / (2 * k * 2 * A),
            "broadens_centreline_A": _broadens(ratios, widths),
            "broadens_edge_A": _broadens(r_edge, widths)}
    table = []
    label = {PER_SWIMMER: "wall distance per swimmer, W = 2d (default)", WHOLE_WIDTH: "whole channel width, W = d"}
    for reading, v in conf.items():
        wtxt = ", ".join(f"{r:.2f} ({W * 1000:.0f} mm): {x:.3f}" for r, W, x in
                         zip(v["d_over_2A"], v["channel_width_m"], v["central_width_over_lambda"]))
        table.append({"claim": "central state broadens over d/2A 0.6-1.2", "factor": "reading of d",
                      "level": label.get(reading, reading),
                      "verdict": _verdict(v["broadens_centreline_A"], missing=v["broadens_centreline_A"] is None),
                      "key number": f"width/lambda at d/2A (W) = {wtxt}; bodies' model opens at d/2A = "
                                    f"{v['model_opening_d_over_2A']:.2f}"})
    v = conf[PER_SWIMMER]
    table.append({"claim": "central state broadens over d/2A 0.6-1.2", "factor": "definition of A",
                  "level": "edge amplitude A + w/2 (default: centre line A)",
                  "verdict": _verdict(v["broadens_edge_A"], missing=v["broadens_edge_A"] is None),
                  "key number": "width/lambda at d/2(A + w/2) = " + ", ".join(
                      f"{r:.2f}: {x:.3f}" for r, x in zip(v["d_over_2A_edge"], v["central_width_over_lambda"]))})
    return conf, table


def _finite_mean(values) -> float:
    v = np.asarray(values, float)
    return float(v[np.isfinite(v)].mean()) if np.isfinite(v).any() else math.nan


def _groups_summary(ds: xr.Dataset) -> dict[str, dict[str, Any]]:
    """Per group case (keyed ``"3 in 0.19 m"``, each with its ``case_id``): slope and RMS residual (95 %
    intervals) of the neighbours against the line, their median lateral spacing, the fractions inside the
    contact-free band and short of the line, and the groups study's verdict against the reference pairs
    (size 2)."""
    out: dict[str, dict[str, Any]] = {}
    ref_rms = None
    for i in range(ds.sizes.get("group_case", 0)):
        c = ds.isel(group_case=i)
        size, w = int(c["group_size"]), float(c["group_channel_width"])
        dphi, dx = c["group_dphi"].values, c["group_dx_over_lambda"].values
        ok = np.isfinite(dphi) & np.isfinite(dx)
        dphi, dx, run_of = dphi[ok], dx[ok], c["group_run"].values[ok]
        fit = C.compatibility_fit(dx, dphi, runs=run_of)  # a run's neighbour pairs: one cluster
        rms = C.rms(c["group_residual_over_lambda"].values[ok], dphi, run_of)
        if size == 2:
            ref_rms = rms
        entry = {"case_id": str(group_case(size, w)), "group_size": size, "channel_width_m": w,
                 "default": bool(c["group_default"]),
                 "n_neighbour_pairs": int(ok.sum()), "slope": fit.slope.to_dict(),
                 "rms_residual_over_lambda": rms.to_dict(),
                 "median_dy_m": float(np.median(c["group_dy"].values[ok])) if ok.any() else math.nan,
                 "fraction_inside_band": float(np.mean(c["group_band_excess"].values[ok] == 0)) if ok.any() else math.nan,
                 "fraction_short_of_line": float(np.mean(np.abs(dx) < np.abs(dphi) / (2 * np.pi))) if ok.any() else math.nan,
                 "follows_line_more_scatter": None, "follows_line_more_scatter_verdict": NO_RESULT}
        if size > 2 and ref_rms is not None:
            entry["follows_line_more_scatter"] = ok = C.group_follows_line(fit.slope, rms, ref_rms)
            entry["follows_line_more_scatter_verdict"] = _verdict(ok, missing=not (
                fit.slope.has_interval and rms.has_interval and ref_rms.has_interval))
        out[f"{size} in {w:g} m"] = entry
    return out


def _group_table(groups: dict[str, dict]) -> list[dict]:
    """The table rows of the groups of three and four (the reference pairs have none)."""
    return [{"claim": f"groups of {g['group_size']} follow the line, more scatter",
             "factor": "neighbour spacing (channel width)",
             "level": f"d = {g['channel_width_m']:g} m" + (" (default)" if g["default"] else ": the pairs' spacing"),
             "verdict": g["follows_line_more_scatter_verdict"],
             "key number": f"slope {stats.Estimate.from_dict(g['slope']):.2f}, RMS "
                           f"{stats.Estimate.from_dict(g['rms_residual_over_lambda']):.3f} lambda, "
                           f"neighbour spacing {g['median_dy_m'] * 1000:.1f} mm"}
            for g in groups.values() if g["group_size"] != 2]


def summary(ds: xr.Dataset) -> dict:
    """Pure: per case the verdict by its claim's criterion and the key numbers (the ``_summary_*`` steps,
    every per-case entry with its ``case_id``); the table (``no result``, :data:`NOT_RUN`, for the rows
    of a skipped factor group); ``skipped_factor_groups`` and the ids of their cases, ``skipped_cases``
    (whose explanations are then not judged: :data:`~._explanations._protocol.NOT_RUN`).  Which look's
    plan each group kept is the study JSON's (``stages``: ``frozen_parts``)."""
    skipped = skipped_groups(ds)
    cases, table = _summary_cases(ds, skipped)
    link_sets, link_rows = _summary_link_sets(cases)
    pot, pot_rows = _summary_impulse(ds)
    conf, conf_rows = _summary_confinement(ds)
    groups = _groups_summary(ds)
    table += (_not_run(link_rows, "links" in skipped) + _not_run(pot_rows, "impulse" in skipped)
              + _not_run(conf_rows, "confinement" in skipped) + _not_run(_group_table(groups), "groups" in skipped))
    out = {"cases": cases, "groups": groups, "confinement": conf, "impulse": pot}
    skipped_cases = sorted(str(c) for c in results_by_case(out) if FACTOR_GROUPS.get(c.case_set) in skipped)
    return {"table": table, "cases": cases,
            "links_equal_A": link_sets.get("links"), "links_sets": link_sets,
            "confinement": conf, "impulse": pot,
            "groups": groups,
            "skipped_factor_groups": [g for g in SKIPPABLE_GROUPS if g in skipped],
            "skipped_cases": skipped_cases,
            "swim_drag_pair_speed_m_s": _finite_mean(ds["swim_drag_pair_speed"].values),
            "impulse_Ns": ds["impulse"].values,
            "amplitude_3_links_m": float(ds["amplitude_3_links"]),
            "criteria": {"pairs": f"slope 95 % interval within 1 +- {LINE_SLOPE_TOL}, RMS upper bound < {LINE_RMS_TOL} "
                                  "lambda (the pairs study's)",
                         "links": "RMS falls at every step in N and the largest N's interval lies below N = 3's",
                         "confinement": f"central width > {WIDTH_TOL} lambda within d/2A <= 1.2, never "
                                        f"shrinking by more than {WIDTH_TOL}"}}


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
