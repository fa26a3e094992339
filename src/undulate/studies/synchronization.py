"""Studies ``synchronization-pairs`` and ``synchronization-groups``: phase and position together.

The paper holds every swimmer's phase fixed; Zhou, Hao & Gravish (Phys.
Rev. X 11, 031051, 2021) let the robots' rhythm emerge from sensing and
report, for pairs of robots in contact:

1. joints synchronize **in phase and anti-phase** through collisions
   (robots held in place);
2. **anti-phase locking disappears** when the robots can adjust their
   position;
3. synchronization **sharply reduces interaction forces**.

``synchronization-pairs`` checks each claim with the three closed-loop families
of :mod:`undulate.control` (``self-oscillating``; ``phase-oscillator`` with
load feedback ``sigma`` = :data:`PAIR_COUPLING`; ``relay``, the closest model to
the PRX robots' oscillator we could build): two swimmers in the paper's
``d = 0.13 m`` channel, initial phase differences spread over ``[-pi, pi)``,
longitudinal positions held (``Scene.hold_x``) or free, run for
:data:`PAIR_DURATION_S` or until :data:`PAIR_SYNC_STOP` finds the lock decided
(the runs of :mod:`._closed_loop_pairs`, shared with ``phase-interaction``).  Per run: the final phase difference (circular mean
over the last :data:`TAIL_S`), the time to lock (:func:`undulate.phases.time_to_lock`,
tolerance :data:`LOCK_TOL_RAD`), and the mean swimmer-swimmer contact force over
the first and the last :data:`TAIL_S`.

``synchronization-groups`` asks the question the paper leaves open: 3 to
10 swimmers side by side, phases and positions both free, random initial
phases (seeded), channel width ``N d_per_swimmer``.  Per run: the order
parameter ``R(t)``, the time ``R`` first stays above :data:`R_LOCKED`, and the
final configuration -- **phase-locked** (every neighbour phase difference
drifts less than :data:`DRIFT_TOL_RAD_S` over the last :data:`TAIL_S`),
**position-compatible** (RMS distance of the neighbours' ``dx`` from the
nearest compatible branch for their current ``dphi`` below
:data:`COMPAT_TOL` wavelengths), both, or neither; and each neighbour pair's
final ``(dphi, dx / lambda)``, judged against the two measured landscapes: the
cohesion potential (its minimum: the compatible branch) and the
phase-interaction function ``H`` of :mod:`.phase_interaction` (measured here
too, a pair in the 0.13 m channel, positions free and held).
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from .. import stats, theory
from ..params import Channel, Scene, SimOptions
from ..stopping import PhaseStop
from ..sweep import batched_sweep_function
from ._criteria import PAIR_CHANNEL_M
from ._phase_probe import CONTROLLERS, PAIR_COUPLING, _label
from ._closed_loop_pairs import (LOCK_TOL_RAD, PAIR_DURATION_S, PAIR_SYNC_STOP, RECORD, TAIL_S,  # noqa: F401
                                 _tail_circmean, closed_loop_pairs_sweep, pair_plan, pair_run, pair_runs, pair_stages)
from ._shared import h_probe_phases, h_probe_sweep
from ._points import SyncPoint
from ._runners import _in_batches, _padded, _simulate_stopped_batch, _stop_vars
from ._context import StudyContext
from ._protocol import Claim, Study, Verdict
from ._registry import register

__all__ = ["pair_run", "pair_runs", "group_run", "group_runs", "free_frequency", "pair_plan", "group_plan", "PAIR_CLAIMS", "GROUP_CLAIMS",
           "CONTROLLERS", "PAIR_COUPLING"]

SYNC_TOL_RAD = math.radians(30.0)
"""A final phase difference within this of 0 (pi) counts as in phase (anti-phase)."""
COLLIDING_N = 0.05
"""Runs whose mean contact force over the first TAIL_S exceeds this (N) collided."""
R_LOCKED = 0.9
GROUP_SYNC_STOP = PAIR_SYNC_STOP
"""The closed-loop groups' stopping rule: the pairs' rule on every pair of swimmers (a group frozen in
a locked state, every phase difference and offset steady, stops; one still moving runs on)."""
DRIFT_TOL_RAD_S = 0.02
COMPAT_TOL = 0.1
NEIGHBOURS = 9
"""Slots for the neighbour pairs' final (dx, dphi) of a group (up to 10 swimmers; NaN-padded)."""


def group_run(point: dict, seed: int, *, duration_s: float = PAIR_DURATION_S, stop: PhaseStop | None = None):
    """One closed-loop group (sweep function).  ``point``: ``controller``, ``n_swimmers``,
    ``spacing_m`` (channel width per swimmer).  Initial phases uniform in [0, 2 pi) from
    ``seed``; positions and phases free.  ``stop``: a stopping rule (:data:`GROUP_SYNC_STOP`;
    None: the whole ``duration_s``); the final values are then over the last :data:`TAIL_S`
    before the stop and ``R`` is NaN after it."""
    return group_runs([point], [seed], duration_s=duration_s, stop=stop)[0]


@batched_sweep_function
def group_runs(points: list[dict], seeds: list[int], *, duration_s: float = PAIR_DURATION_S,
               stop: PhaseStop | None = None):
    """:func:`group_run` on several points (batched sweep function): the groups of one controller
    and size are stepped together, each stopping by its own rule (bitwise its run alone)."""
    pts = [SyncPoint.of(p) for p in points]
    opts = SimOptions(duration_s=duration_s, sample_rate_hz=10.0, record=RECORD)

    def run(key, idx):
        scenes = [Scene(phases_rad=tuple(np.random.default_rng(seeds[i]).uniform(0, 2 * np.pi, key[1])),
                        channel=Channel(width_m=key[1] * pts[i].spacing_m), controller=CONTROLLERS[key[0]])
                  for i in idx]
        dss, n_full = _simulate_stopped_batch(scenes, opts, stop)
        return [_group_result(sc, ds, n_full) for sc, ds in zip(scenes, dss)]

    return _in_batches([(p.controller, p.n_swimmers) for p in pts], run)


def _group_result(sc: Scene, ds, n_full: int):
    """A closed-loop group's run -> R(t), lock time, phase-locked / compatible, neighbours' finals."""
    import xarray as xr

    from ..observables import neighbour_offsets
    from ..phases import gait_frequency, gait_phase, neighbour_phase_differences, order_parameter

    t = ds["time"].values
    psi = gait_phase(ds)
    r = order_parameter(psi).values
    above = r >= R_LOCKED
    lock = np.nan
    if above[-1]:
        below = np.flatnonzero(~above)
        lock = float(t[0] if below.size == 0 else t[below[-1] + 1])
    tail = t >= t[-1] - TAIL_S
    d = neighbour_phase_differences(ds).values  # (time, rank)
    drift = np.abs(np.angle(np.exp(1j * (d[tail][-1] - d[tail][0])))) / TAIL_S
    locked = bool((drift < DRIFT_TOL_RAD_S).all())
    off = neighbour_offsets(ds)
    lam = sc.wavelength_m
    dx = off["dx"].values[tail].mean(axis=0)
    dphi_end = _tail_circmean(d, tail)
    res = theory.compatibility_residual(dx, dphi_end, lam) / lam
    compat_rms = float(np.sqrt(np.mean(res ** 2)))
    pad = np.full(NEIGHBOURS, np.nan)
    return xr.Dataset({
        "R": (("time",), _padded(r, n_full), {"units": "1", "long_name": "order parameter R(t) (NaN after a stop)"}),
        "R_final": ((), float(r[tail].mean()), {"units": "1", "long_name": "mean R over the last TAIL_S"}),
        "lock_time": ((), lock, {"units": "s", "long_name": "time after which R stays >= R_LOCKED (NaN: never)"}),
        "phase_locked": ((), int(locked), {"units": "1", "long_name": "1 if every neighbour dphi drifts < DRIFT_TOL_RAD_S"}),
        "compat_rms": ((), compat_rms, {"units": "1", "long_name": "RMS compatibility residual / lambda, last TAIL_S"}),
        "max_drift": ((), float(drift.max()), {"units": "rad/s", "long_name": "fastest neighbour dphi drift, last TAIL_S"}),
        "dx_final": (("neighbour",), np.concatenate([dx / lam, pad])[:NEIGHBOURS],
                     {"units": "1", "long_name": "neighbour dx / lambda, mean over the last TAIL_S (NaN: no pair)"}),
        "dphi_final": (("neighbour",), np.concatenate([dphi_end, pad])[:NEIGHBOURS],
                       {"units": "rad", "long_name": "neighbour dphi, circular mean over the last TAIL_S"}),
        "frequency": ((), float(gait_frequency(psi, t_from=t[-1] - TAIL_S).mean()),
                      {"units": "Hz", "long_name": "collective gait frequency (mean over swimmers), last TAIL_S"}),
        **_stop_vars(ds),
    }, coords={"time": ("time", np.round(np.arange(n_full) * float(ds.attrs["sample_interval"]), 12),
                        {"units": "s"})})


def free_frequency(point: dict, seed: int, *, duration_s: float = 30.0):
    """The gait frequency of a lone swimmer under ``point["controller"]`` (wide channel, no
    contact) over its last :data:`TAIL_S` (sweep function): ``frequency`` (Hz)."""
    import xarray as xr

    from ..phases import gait_frequency, gait_phase
    from ..simulation import simulate

    sc = Scene(phases_rad=(0.0,), channel=Channel(width_m=2.0), controller=CONTROLLERS[SyncPoint.of(point).controller])
    ds = simulate(sc, SimOptions(duration_s=duration_s, record=("gait_phase",)))
    f = float(gait_frequency(gait_phase(ds), t_from=duration_s - TAIL_S)[0])
    return xr.Dataset({"frequency": ((), f, {"units": "Hz", "long_name": "free gait frequency"})})


def group_plan(quick: bool) -> dict[str, Any]:
    return {"n_swimmers": [3, 5] if quick else [3, 5, 10], "spacing_m": [0.055, 0.065],
            "dphi_rad": h_probe_phases(quick),
            "replicates": 2 if quick else 4, "duration_s": PAIR_DURATION_S if quick else 2 * PAIR_DURATION_S}


def group_stages(quick: bool) -> tuple[dict[str, Any], ...]:
    """:func:`group_plan` in looks: more replicates per look (quick 1, 2; full 1, 2, 4)."""
    p = group_plan(quick)
    return tuple({**p, "replicates": r} for r in ((1, 2) if quick else (1, 2, 4)))


def _fraction(mask: np.ndarray, of: np.ndarray) -> tuple[int, int]:
    return int((mask & of).sum()), int(of.sum())


E = stats.Estimate.from_dict


def _held_lock(c: str):
    def judge(s: dict) -> Verdict:
        v = s["per_controller"][c]
        ni, nc = v["held_synchronized"], v["held_colliding"]
        if nc == 0:
            return Verdict.none("no held run collided", value=v)
        tol = f"{math.degrees(SYNC_TOL_RAD):.0f} deg"
        quiet = v["n_held"] - nc
        measured = (f"{ni}/{nc} colliding held runs end within {tol} of 0 or pi (in phase "
                    f"{v['held_colliding_in_phase']}, anti-phase {v['held_colliding_anti_phase']})")
        if quiet:  # counted apart: in phase without ever touching is not synchronization through contact
            measured += (f"; the {quiet} held runs that never collided: in phase "
                         f"{v['held_in_phase'] - v['held_colliding_in_phase']}, "
                         f"anti-phase {v['held_anti_phase'] - v['held_colliding_anti_phase']}")
        return Verdict.of([stats.Check.exact(ni == nc, f"{ni}/{nc} colliding held runs synchronized")], measured,
                          {"synchronized": ni, "colliding": nc, "in_phase": v["held_colliding_in_phase"],
                           "anti_phase": v["held_colliding_anti_phase"]})
    return judge


def _anti_phase_disappears(c: str):
    def judge(s: dict) -> Verdict:
        v = s["per_controller"][c]
        ha, fa, nh, nf = v["held_anti_phase"], v["free_anti_phase"], v["n_held"], v["n_free"]
        measured = (f"runs ending within {math.degrees(SYNC_TOL_RAD):.0f} deg of pi: held {ha}/{nh}, free {fa}/{nf}"
                    if ha else f"no held run ends anti-phase (0/{nh}; free: {fa}/{nf}): the premise fails in this model")
        return Verdict.of([stats.Check.exact(fa < ha, f"free {fa} < held {ha} anti-phase runs")], measured,
                          {"held_anti_phase": ha, "free_anti_phase": fa, "n_held": nh, "n_free": nf})
    return judge


FORCE_RATIO_MAX = 0.5
"""Claim: the median last/first contact-force ratio over colliding runs lies below this."""


def _force_drops(c: str):
    def judge(s: dict) -> Verdict:
        r = E(s["per_controller"][c]["force_ratio"])
        if not r.finite:
            return Verdict.none("no run collided", value=r.to_dict())
        measured = (f"median last/first-{TAIL_S:g}-s contact force over {r.n} colliding runs (held and free) "
                    f"{r:.2f}")
        if not r.has_interval:
            return Verdict.none("fewer than 3 colliding runs (no interval for the median)", measured, r.to_dict())
        return Verdict.of([r.below(FORCE_RATIO_MAX, "median contact-force ratio")], measured, r.to_dict())
    return judge


PAIR_CLAIMS = tuple(claim for c in CONTROLLERS for claim in (
    Claim(f"{c}: held pairs that collide lock in phase or anti-phase",
          "PRX 2021: robot joints synchronize to in-phase and anti-phase oscillations through collisions",
          "every colliding held run ends within 30 deg of 0 or pi", _held_lock(c),
          quote="in-phase and anti-phase locking when positions are held", where="PRX 2021 (Zhou, Hao & Gravish, Phys. Rev. X 11, 031051), as SPEC.md §6 states it"),
    Claim(f"{c}: anti-phase locking disappears when positions are free",
          "PRX 2021: when the robots can adjust their position anti-phase synchronization is no longer observed",
          "fewer free runs than held runs end anti-phase", _anti_phase_disappears(c),
          quote="no anti-phase locking when robots can move", where="PRX 2021 (Zhou, Hao & Gravish, Phys. Rev. X 11, 031051), as SPEC.md §6 states it"),
    Claim(f"{c}: synchronization sharply reduces the interaction force",
          "PRX 2021: synchronization dramatically reduces interaction forces",
          "the 95 % interval (bootstrap) of the median last/first contact-force ratio over colliding runs "
          f"lies below {FORCE_RATIO_MAX} (fails if it lies wholly above; undecided if it straddles it)",
          _force_drops(c),
          quote="much smaller contact forces once synchronized", where="PRX 2021 (Zhou, Hao & Gravish, Phys. Rev. X 11, 031051), as SPEC.md §6 states it"),
))


def _groups_end_both(c: str):
    def judge(s: dict) -> Verdict:
        v = s["per_controller"][c]
        n, both, locked, compat = v["n_runs"], v["both"], v["phase_locked"], v["compatible"]
        if n == 0:
            return Verdict.none("no group run has a result")
        return Verdict.of([stats.Check.exact(both > n / 2, f"{both}/{n} runs both")], (
            f"{both}/{n} runs both, {locked}/{n} phase-locked, {compat}/{n} compatible (RMS < {COMPAT_TOL} lambda); "
            f"median final R {v['median_R_final']:.2f}; collective {v['median_collective_frequency_hz']:.3f} Hz vs "
            f"free {v['free_frequency_hz']:.3f} Hz"), {"both": both, "n_runs": n})
    return judge


def _groups_as_predicted(c: str):
    def judge(s: dict) -> Verdict:
        v = s["per_controller"][c]
        n, hf = v["n_neighbour_pairs"], v["H_free"]
        if n == 0:
            return Verdict.none("no group run has a result")
        k = hf["neighbour_predicted_and_compatible"]
        zs = ", ".join(f"{math.degrees(z['zero_rad']):.0f} deg" for z in hf["stable_zeros"]) or "none"
        return Verdict.of([stats.Check.exact(k >= 0.8 * n, f"{k}/{n} neighbour pairs")], (
            f"{k}/{n} neighbour pairs end where both landscapes predict (H with positions free: stable zeros {zs}, "
            f"{len(hf['neutral_bins'])}/{len(hf['bins'])} grid points neutral; {hf['neighbour_predicted']}/{n} at a "
            f"state H predicts, {v['neighbour_compatible']}/{n} on a compatible branch within {COMPAT_TOL} lambda)"),
            {"predicted_and_compatible": k, "n_neighbour_pairs": n})
    return judge


GROUP_CLAIMS = tuple(claim for c in CONTROLLERS for claim in (
    Claim(f"{c}: groups with phase and position free end phase-locked and position-compatible",
          "open (paper's conclusion): phase dynamics together with position dynamics",
          "most runs end both phase-locked and position-compatible", _groups_end_both(c),
          quote=("The paper holds phases fixed; its conclusion leaves phase dynamics open. ... `undulate` "
                 "simulates phase and position dynamics together"),
          where="SPEC.md §6 (beyond the paper: its conclusion leaves phase dynamics open)"),
    Claim(f"{c}: groups synchronize as the measured phase interaction predicts",
          "PRX 2021: collectives synchronize their movements through contact as predicted by the theory",
          "at least 80 % of neighbour pairs end at a state H (positions free) predicts -- a stable zero or a "
          "neutral band -- and on a compatible branch (the cohesion potential's minimum)", _groups_as_predicted(c),
          quote=("Together, the two measured landscapes should explain where groups with free phases and free "
                 "positions end."),
          where="PRX 2021 (Zhou, Hao & Gravish, Phys. Rev. X 11, 031051), as SPEC.md §6 states it: phase reduction"),
))


def _median(a):
    return float(np.median(a)) if np.size(a) else float("nan")


def pair_summary(ds) -> dict[str, Any]:
    """Pure: per controller, counts of locked / colliding runs and the force ratio (bootstrap interval)."""
    out: dict[str, Any] = {"per_controller": {}, "n_failed": int(ds["run_failed"].values.sum())}
    for c in ds["controller"].values:
        v = ds.sel(controller=c).isel(replicate=0)
        final = v["dphi_final"].values  # (hold_x, dphi0)
        fs, fe = v["force_start"].values, v["force_end"].values
        held = v["hold_x"].values.astype(bool)
        collide = fs > COLLIDING_N
        in_phase = np.abs(final) < SYNC_TOL_RAD
        anti = np.abs(final) > np.pi - SYNC_TOL_RAD
        hsel = np.broadcast_to(held[:, None], final.shape)
        done = np.isfinite(final)  # a failed run has no final phase difference
        ratio = fe[collide] / fs[collide]
        # the median is not smooth (its jackknife takes two values): BCa gains nothing on it, so the
        # percentile interval (explorations/interval_coverage.py --median)
        se, lo, hi = stats.bootstrap(_median, ratio, method="percentile")
        out["per_controller"][str(c)] = {
            "force_ratio": stats.Estimate(_median(ratio), se, lo, hi, int(ratio.size),
                                          "median, bootstrap percentile", stats.level(), int(ratio.size),
                                          int(ratio.size) - 1).to_dict(),
            "n_held": int((done & hsel).sum()),
            "n_free": int((done & ~hsel).sum()),
            "held_colliding": int((collide & done & hsel).sum()),
            "held_synchronized": int(((in_phase | anti) & collide & hsel).sum()),
            "held_colliding_in_phase": int((in_phase & collide & hsel).sum()),
            "held_colliding_anti_phase": int((anti & collide & hsel).sum()),
            "held_in_phase": int((in_phase & hsel).sum()),
            "held_anti_phase": int((anti & hsel).sum()),
            "free_anti_phase": int((anti & ~hsel).sum()),
            "free_in_phase": int((in_phase & ~hsel).sum()),
            "median_force_ratio": float(np.median(ratio)) if ratio.size else float("nan"),
            "median_lock_time_s": float(np.nanmedian(v["lock_time"].values)) if np.isfinite(v["lock_time"].values).any() else float("nan"),
        }
    return out


def pair_dataset(ctx: StudyContext, p: dict[str, Any]):
    ds = _label(ctx.shared_sweep("closed-loop-pairs", *closed_loop_pairs_sweep(p["dphi0_rad"], p["duration_s"],
                                                                               ctx.seed)))
    ds["dphi0_rad"].attrs.update(units="rad", long_name="initial phase difference phi_1 - phi_0")
    ds.attrs.update(title="closed-loop pairs: phase locking", channel_width_m=PAIR_CHANNEL_M,
                    duration_s=p["duration_s"], phase_oscillator_coupling=PAIR_COUPLING)
    return ds


def group_dataset(ctx: StudyContext, p: dict[str, Any]):
    from ..sweep import Grid

    grid = Grid(axes={"controller": list(CONTROLLERS), "n_swimmers": p["n_swimmers"], "spacing_m": p["spacing_m"]},
                replicates=p["replicates"], seed=ctx.seed)
    runs, free, probe = ctx.together(  # independent: side by side where the study runs wide
        lambda: ctx.sweep("runs", functools.partial(group_runs, duration_s=p["duration_s"], stop=GROUP_SYNC_STOP),
                          grid),
        lambda: ctx.sweep("free", free_frequency, Grid(axes={"controller": list(CONTROLLERS)}, seed=ctx.seed)),
        lambda: ctx.shared_sweep("h-probe", *h_probe_sweep(p["dphi_rad"], ctx.seed)))
    ds = _label(runs)
    ds["free_frequency"] = ("controller", free["frequency"].isel(replicate=0).values,
                            {"units": "Hz", "long_name": "gait frequency of a lone swimmer, last TAIL_S"})
    ds["H"] = probe["H"].isel(replicate=0).rename(hold_x="probe_hold_x")
    ds["dphi_rad"].attrs.update(units="rad", long_name="held phase difference of the H probe (pair, 0.13 m)")
    ds["spacing_m"].attrs.update(units="m", long_name="channel width per swimmer")
    ds["n_swimmers"].attrs.update(units="1")
    ds.attrs.update(title="closed-loop groups: phase and position free", duration_s=p["duration_s"],
                    phase_oscillator_coupling=PAIR_COUPLING)
    return ds


def group_summary(ds) -> dict[str, Any]:
    """Pure: per controller, how many runs end phase-locked, compatible, both; R and frequencies."""
    per = {}
    for c in ds["controller"].values:
        v = ds.sel(controller=c)
        ok = np.isfinite(v["R_final"].values)
        locked = v["phase_locked"].values.astype(bool) & ok
        compat = (v["compat_rms"].values < COMPAT_TOL) & ok
        per[str(c)] = {"n_runs": int(ok.sum()), "phase_locked": int(locked.sum()), "compatible": int(compat.sum()),
                       "free_frequency_hz": float(v["free_frequency"]),
                       "median_collective_frequency_hz": float(np.nanmedian(v["frequency"].values)),
                       "both": int((locked & compat).sum()),
                       "median_R_final": float(np.nanmedian(v["R_final"].values)),
                       "median_lock_time_s": float(np.nanmedian(v["lock_time"].values))
                       if np.isfinite(v["lock_time"].values).any() else float("nan"),
                       **_landscapes(v, ds["H"].sel(law=c))}
    return {"per_controller": per, "n_failed": int(ds["run_failed"].values.sum())}


def _landscapes(v, h) -> dict[str, Any]:
    """Pure: where the neighbour pairs end in the (dphi, dx) plane against the two measured landscapes:
    the cohesion potential (compatible branch dx = lambda dphi / 2 pi + n lambda) and H(dphi) with
    positions free and held (stable zeros or neutral bands: :func:`.phase_interaction.predicted`)."""
    from ._phase_probe import _neutral, predicted, stable_zeros

    dx, dp = v["dx_final"].values.ravel(), v["dphi_final"].values.ravel()
    ok = np.isfinite(dx) & np.isfinite(dp)
    dx, dp = dx[ok], dp[ok]
    compat = np.abs(theory.compatibility_residual(dx, dp, 1.0)) < COMPAT_TOL
    out: dict[str, Any] = {"n_neighbour_pairs": int(ok.sum()), "neighbour_compatible": int(compat.sum()),
                           "neighbour_dphi_rad": dp.tolist(), "neighbour_dx_lambda": dx.tolist()}
    for cond, held in (("free", False), ("held", True)):
        hh = h.sel(probe_hold_x=held)
        bins = [{"centre": float(d), "H": stats.mean(hh.sel(dphi_rad=d).values).to_dict()} for d in hh["dphi_rad"].values]
        zeros = stable_zeros(bins)
        on = np.array([predicted(f, zeros, bins) for f in dp], dtype=bool)
        out[f"H_{cond}"] = {"stable_zeros": zeros, "neutral_bins": _neutral(bins), "bins": bins,
                            "all_neutral": len(_neutral(bins)) == len(bins), "neighbour_predicted": int(on.sum()),
                            "neighbour_predicted_and_compatible": int((on & compat).sum())}
    return out


def _plot_pairs(ds):
    from ..plotting.synchronization import plot_sync_pairs

    return plot_sync_pairs(ds)


def _plot_groups(ds):
    from ..plotting.synchronization import plot_sync_groups

    return plot_sync_groups(ds, group_summary(ds))


register(Study(
    name="synchronization-pairs", plan=pair_plan, stages=pair_stages, dataset=pair_dataset, summary=pair_summary, claims=PAIR_CLAIMS, reference="prx2021",
    figure=_plot_pairs,
    description="Closed-loop pairs (self-oscillating; phase oscillator with load feedback; relay) in the "
                "d = 0.13 m channel, positions held vs free: final phase difference, time to lock, "
                "contact force before and after (PRX 2021's three claims)."))
register(Study(
    name="synchronization-groups", plan=group_plan, stages=group_stages, dataset=group_dataset, summary=group_summary,
    claims=GROUP_CLAIMS, figure=_plot_groups, reference="prx2021",
    description="3-10 closed-loop swimmers, phases and positions free: order parameter R(t), time to "
                "lock, whether the final state is phase-locked, position-compatible, or both, and where the "
                "neighbour pairs end in the (dphi, dx) plane against the compatible branches and H(dphi)."))
