"""The sensitivity study's runs (:mod:`.sensitivity`), one factor group a step.

Each ``_data_*`` step makes one factor group's cases from its runs on the plan it is handed
(:class:`_Runs`: the context, the plan, its dphi, the 3-link amplitude and the groups not run): the
xi = 1 model levels and steady windows, xi = 3/2, the equal-A and guided link numbers, the readings of
d, the groups against their neighbours' spacing, the swimming ground and the impulse drags.  A group
not run makes its cases as NaN rows without a run.  :func:`.sensitivity.dataset` composes them.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np
import xarray as xr

from .. import theory
from ..observables import steady_state
from ..params import SwimmerGeometry
from ..sweep import Grid
from . import _analysis as analysis
from ._criteria import PAIR_CHANNEL_M
from ._gaits import equal_amplitude_beta
from ._context import StudyContext
from ._runners import BODY_LENGTH_M, PAIR_STOP, PERIOD_S, RECORD_HZ, group_point, pair_point
from ._sensitivity_design import (
    BETA_DEG, CONFINEMENT_S, DEFAULT_BODY_M, DEFAULT_S, DURATIONS_S, FLUID_DENSITIES,
    IMPULSE_DRAG_DEFAULT, IMPULSE_DRAGS_N_S_PER_M, LEFT_OUT, LONG_S, MODEL_DEFAULTS, MODEL_LEVELS,
    PAPER_RANGE_HIGH, SWIM_DRAG_N_S_PER_M, D_READING_SCALE, D_READINGS, PER_SWIMMER, WINDOWS, CaseId,
    CaseSet, Plan, group_cases, impulse_drags, xi32_durations)
from ._shared import group_part, group_sweep, impulse_sweep


def _timestep(n_links: int) -> float:
    from ..params import Scene
    from ..scene import auto_timestep

    return auto_timestep(Scene(geometry=SwimmerGeometry(n_links=n_links)))


def _cut(run: xr.Dataset, duration_s: float) -> xr.Dataset:
    return run.sel(time=slice(None, duration_s + 1e-9))


def _pair_rows(run: xr.Dataset, dphi: float, lam: float, amp: float, windows=(3,)) -> dict[int, tuple]:
    """Final dx/lambda, residual/lambda and steady flag of one pair run per steady window."""
    rec, series = analysis.pair_record(run, dphi, lam, amp)
    out = {}
    for w in windows:
        if w == analysis.STEADY_WINDOW:
            out[w] = (rec["dx_steady"] / lam, rec["residual"] / lam, rec["steady"])
            continue
        da = xr.DataArray(series / lam, coords={"time": run["time"].values}, dims="time")
        st = steady_state(da, PERIOD_S, tol=analysis.STEADY_TOL, window=w)
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
        out[analysis.positions(self.dphis, dphis)] = values
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
            for w in WINDOWS if w != analysis.STEADY_WINDOW]
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
        shared = w == {2: PAIR_CHANNEL_M, **analysis.GROUP_CHANNEL_M}[n]  # the groups study's own runs
        sw = (r.ctx.shared_sweep if shared else r.ctx.sweep)(group_part(n, w), fn, grid)
        return [run for run in analysis.sweep_runs(sw) if run is not None]

    cases = group_cases()  # the groups study's grid: the same per-run seeds, hence the same phase draws
    runs = r.ctx.together(*(functools.partial(group_runs, n, w) for n, w, _ in cases))
    recs = [[{**rec, "run": i} for i, run in enumerate(rs)
             for rec in analysis.group_records(analysis.trajectory(run, BODY_LENGTH_M), r.A3)] for rs in runs]
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
