"""Studies ``synchronization-pairs`` and ``synchronization-groups``: phase and position together.

The paper holds every swimmer's phase fixed; Zhou, Hao & Gravish (Phys.
Rev. X 11, 031051, 2021) let the robots' rhythm emerge from sensing and
report, for pairs of robots in contact:

1. joints synchronize **in phase and anti-phase** through collisions
   (robots held in place);
2. **anti-phase locking disappears** when the robots can adjust their
   position;
3. synchronization **sharply reduces interaction forces**.

``synchronization-pairs`` checks each claim with both closed-loop families
of :mod:`undulate.control` (``self-oscillating``; ``phase-oscillator`` with
load feedback ``sigma`` = :data:`PAIR_COUPLING`): two swimmers in the paper's
``d = 0.13 m`` channel, initial phase differences spread over ``[-pi, pi)``,
longitudinal positions held (``Scene.hold_x``) or free, run for
:data:`PAIR_DURATION_S`.  Per run: the final phase difference (circular mean
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
:data:`COMPAT_TOL` wavelengths), both, or neither.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import Any

import numpy as np

from .. import theory
from ..params import Channel, ControllerParams, Scene, SimOptions
from ._registry import StudyConfig, StudyResult, register

__all__ = ["pair_run", "group_run", "pair_plan", "group_plan", "pair_claims", "group_claims",
           "CONTROLLERS", "PAIR_COUPLING"]

PAIR_CHANNEL_M = 0.13
PAIR_COUPLING = 2.0
"""phase-oscillator load feedback sigma in these studies, rad/s per N m."""
CONTROLLERS = {"self-oscillating": ControllerParams(kind="self-oscillating"),
               "phase-oscillator": ControllerParams(kind="phase-oscillator", coupling=PAIR_COUPLING)}
PAIR_DURATION_S = 60.0
TAIL_S = 10.0
LOCK_TOL_RAD = 0.15
SYNC_TOL_RAD = math.radians(30.0)
"""A final phase difference within this of 0 (pi) counts as in phase (anti-phase)."""
COLLIDING_N = 0.05
"""Runs whose mean contact force over the first TAIL_S exceeds this (N) collided."""
R_LOCKED = 0.9
DRIFT_TOL_RAD_S = 0.02
COMPAT_TOL = 0.1
RECORD = ("x", "y", "joint_angle", "joint_command", "joint_error", "contact_force_pair", "gait_phase")


def _sweep_dir(config: StudyConfig, name: str) -> Path:
    mode = "quick" if config.quick else "full"
    return Path(config.out_dir) / ".sweeps" / name / f"runs-{mode}-seed{config.seed}"


def _label(ds):
    """Units on the sweep's bookkeeping variables (run index and seed: dimensionless)."""
    for v in ("replicate", "seed", "run_failed"):
        if v in ds.variables:
            ds[v].attrs.setdefault("units", "1")
    return ds


def _tail_circmean(a: np.ndarray, sel: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * a[sel]).mean(axis=0))


def pair_run(point: dict, seed: int, *, duration_s: float = PAIR_DURATION_S):
    """One closed-loop pair (sweep function).  ``point``: ``controller`` (a key of
    :data:`CONTROLLERS`), ``hold_x`` (bool), ``dphi0_rad`` (initial phi_1 - phi_0).
    Deterministic (``seed`` unused)."""
    import xarray as xr

    from ..phases import neighbour_phase_differences, time_to_lock
    from ..simulation import simulate

    sc = Scene(phases_rad=(0.0, float(point["dphi0_rad"])), channel=Channel(width_m=PAIR_CHANNEL_M),
               hold_x=bool(point["hold_x"]), controller=CONTROLLERS[str(point["controller"])])
    ds = simulate(sc, SimOptions(duration_s=duration_s, sample_rate_hz=20.0, record=RECORD))
    t = ds["time"].values
    d = neighbour_phase_differences(ds)
    f = ds["contact_force_pair"].values[:, 0]
    head, tail = t <= t[0] + TAIL_S, t >= t[-1] - TAIL_S
    return xr.Dataset({
        "dphi_final": ((), float(_tail_circmean(d.values[:, 0], tail)),
                       {"units": "rad", "long_name": "final phase difference (circular mean, last TAIL_S)"}),
        "lock_time": ((), float(time_to_lock(d, tol_rad=LOCK_TOL_RAD, hold_s=TAIL_S)[0]),
                      {"units": "s", "long_name": "time to lock (NaN: still drifting)"}),
        "force_start": ((), float(f[head].mean()), {"units": "N", "long_name": "mean contact force, first TAIL_S"}),
        "force_end": ((), float(f[tail].mean()), {"units": "N", "long_name": "mean contact force, last TAIL_S"}),
        "dphi": (("time",), d.values[:, 0], {"units": "rad", "long_name": "phase difference over time"}),
    }, coords={"time": ("time", t, {"units": "s"})})


def group_run(point: dict, seed: int, *, duration_s: float = PAIR_DURATION_S):
    """One closed-loop group (sweep function).  ``point``: ``controller``, ``n_swimmers``,
    ``spacing_m`` (channel width per swimmer).  Initial phases uniform in [0, 2 pi) from
    ``seed``; positions and phases free."""
    import xarray as xr

    from ..observables import neighbour_offsets
    from ..phases import gait_frequency, gait_phase, neighbour_phase_differences, order_parameter
    from ..simulation import simulate

    n = int(point["n_swimmers"])
    phases = tuple(np.random.default_rng(seed).uniform(0, 2 * np.pi, n))
    sc = Scene(phases_rad=phases, channel=Channel(width_m=n * float(point["spacing_m"])),
               controller=CONTROLLERS[str(point["controller"])])
    ds = simulate(sc, SimOptions(duration_s=duration_s, sample_rate_hz=10.0, record=RECORD))
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
    res = theory.compatibility_residual(dx, _tail_circmean(d, tail), lam) / lam
    compat_rms = float(np.sqrt(np.mean(res ** 2)))
    return xr.Dataset({
        "R": (("time",), r, {"units": "1", "long_name": "order parameter R(t)"}),
        "R_final": ((), float(r[tail].mean()), {"units": "1", "long_name": "mean R over the last TAIL_S"}),
        "lock_time": ((), lock, {"units": "s", "long_name": "time after which R stays >= R_LOCKED (NaN: never)"}),
        "phase_locked": ((), int(locked), {"units": "1", "long_name": "1 if every neighbour dphi drifts < DRIFT_TOL_RAD_S"}),
        "compat_rms": ((), compat_rms, {"units": "1", "long_name": "RMS compatibility residual / lambda, last TAIL_S"}),
        "max_drift": ((), float(drift.max()), {"units": "rad/s", "long_name": "fastest neighbour dphi drift, last TAIL_S"}),
        "frequency": ((), float(gait_frequency(psi, t_from=t[-1] - TAIL_S).mean()),
                      {"units": "Hz", "long_name": "collective gait frequency (mean over swimmers), last TAIL_S"}),
    }, coords={"time": ("time", t, {"units": "s"})})


def free_frequency_hz(controller: str, duration_s: float = 30.0) -> float:
    """The gait frequency of a lone swimmer under ``controller`` (wide channel, no contact), Hz,
    over its last :data:`TAIL_S`."""
    from ..phases import gait_frequency, gait_phase
    from ..simulation import simulate

    sc = Scene(phases_rad=(0.0,), channel=Channel(width_m=2.0), controller=CONTROLLERS[controller])
    ds = simulate(sc, SimOptions(duration_s=duration_s, record=("gait_phase",)))
    return float(gait_frequency(gait_phase(ds), t_from=duration_s - TAIL_S)[0])


def pair_plan(quick: bool) -> dict[str, Any]:
    n = 12 if quick else 24
    return {"dphi0_rad": list(np.linspace(-np.pi, np.pi, n, endpoint=False) + np.pi / n),
            "duration_s": PAIR_DURATION_S if quick else 2 * PAIR_DURATION_S}


def group_plan(quick: bool) -> dict[str, Any]:
    return {"n_swimmers": [3, 5] if quick else [3, 5, 10], "spacing_m": [0.055, 0.065],
            "replicates": 2 if quick else 4, "duration_s": PAIR_DURATION_S if quick else 2 * PAIR_DURATION_S}


def _fraction(mask: np.ndarray, of: np.ndarray) -> tuple[int, int]:
    return int((mask & of).sum()), int(of.sum())


def pair_claims(s: dict[str, Any]) -> list[dict[str, Any]]:
    """The PRX 2021 pair claims, one row per controller family, from the summary."""
    rows = []
    for c, v in s["per_controller"].items():
        ni, nc = v["held_synchronized"], v["held_colliding"]
        holds = None if nc == 0 else ni == nc
        rows.append({"claim": f"{c}: held pairs that collide lock in phase or anti-phase",
                     "paper": "PRX 2021: robot joints synchronize to in-phase and anti-phase oscillations "
                              "through collisions",
                     "measured": (f"{ni}/{nc} colliding held runs end within {math.degrees(SYNC_TOL_RAD):.0f} deg "
                                  f"of 0 or pi (in phase {v['held_in_phase']}, anti-phase {v['held_anti_phase']}; "
                                  "holds if all do)") if nc else "no result: no held run collided",
                     "holds": holds})
        ha, fa = v["held_anti_phase"], v["free_anti_phase"]
        holds = fa < ha  # no held anti-phase lock at all: the model shows nothing that could disappear
        rows.append({"claim": f"{c}: anti-phase locking disappears when positions are free",
                     "paper": "PRX 2021: when the robots can adjust their position anti-phase synchronization "
                              "is no longer observed",
                     "measured": (f"anti-phase finals: held {ha}, free {fa} "
                                  "(holds if fewer free than held)") if ha else
                     f"no held run locked anti-phase (free: {fa}): the premise fails in this model",
                     "holds": holds})
        ratio = v["median_force_ratio"]
        holds = None if not math.isfinite(ratio) else ratio < 0.5
        rows.append({"claim": f"{c}: synchronization sharply reduces the interaction force",
                     "paper": "PRX 2021: synchronization dramatically reduces interaction forces",
                     "measured": (f"median last/first-{TAIL_S:g}-s contact force over colliding runs {ratio:.2f} "
                                  "(holds if < 0.5)") if math.isfinite(ratio) else "no result: no run collided",
                     "holds": holds})
    return rows


def group_claims(s: dict[str, Any]) -> list[dict[str, Any]]:
    rows = []
    for c, v in s["per_controller"].items():
        n, both, locked, compat = v["n_runs"], v["both"], v["phase_locked"], v["compatible"]
        rows.append({"claim": f"{c}: groups with phase and position free end phase-locked and position-compatible",
                     "paper": "open (paper's conclusion): phase dynamics together with position dynamics",
                     "measured": (f"{both}/{n} runs both, {locked}/{n} phase-locked, {compat}/{n} compatible "
                                  f"(RMS < {COMPAT_TOL} lambda); median final R {v['median_R_final']:.2f}; "
                                  f"collective {v['median_collective_frequency_hz']:.3f} Hz vs free "
                                  f"{v['free_frequency_hz']:.3f} Hz (holds if most runs end both)") if n else "no result",
                     "holds": None if n == 0 else both > n / 2})
    return rows


def _pair_summary(ds) -> dict[str, Any]:
    out: dict[str, Any] = {"per_controller": {}}
    for c in ds["controller"].values:
        v = ds.sel(controller=c).isel(replicate=0)
        final = v["dphi_final"].values  # (hold_x, dphi0)
        fs, fe = v["force_start"].values, v["force_end"].values
        held = v["hold_x"].values.astype(bool)
        collide = fs > COLLIDING_N
        in_phase = np.abs(final) < SYNC_TOL_RAD
        anti = np.abs(final) > np.pi - SYNC_TOL_RAD
        hsel = np.broadcast_to(held[:, None], final.shape)
        ratio = fe[collide] / fs[collide]
        out["per_controller"][str(c)] = {
            "held_colliding": int((collide & hsel).sum()),
            "held_synchronized": int(((in_phase | anti) & collide & hsel).sum()),
            "held_in_phase": int((in_phase & hsel).sum()),
            "held_anti_phase": int((anti & hsel).sum()),
            "free_anti_phase": int((anti & ~hsel).sum()),
            "free_in_phase": int((in_phase & ~hsel).sum()),
            "median_force_ratio": float(np.median(ratio)) if ratio.size else float("nan"),
            "median_lock_time_s": float(np.nanmedian(v["lock_time"].values)) if np.isfinite(v["lock_time"].values).any() else float("nan"),
        }
    return out


@register("synchronization-pairs", paper_figure=None,
          description="Closed-loop pairs (self-oscillating; phase oscillator with load feedback) in the "
                      "d = 0.13 m channel, positions held vs free: final phase difference, time to lock, "
                      "contact force before and after (PRX 2021's three claims).")
def run_pairs(config: StudyConfig) -> StudyResult:
    from ..plotting.synchronization import plot_sync_pairs
    from ..sweep import Grid, run_sweep

    p = pair_plan(config.quick)
    grid = Grid(axes={"controller": list(CONTROLLERS), "hold_x": [True, False], "dphi0_rad": p["dphi0_rad"]},
                seed=config.seed)
    fn = functools.partial(pair_run, duration_s=p["duration_s"])
    res = run_sweep(fn, grid, _sweep_dir(config, "synchronization-pairs"), scheduler=config.scheduler)
    ds = _label(res.dataset)
    ds["dphi0_rad"].attrs.update(units="rad", long_name="initial phase difference phi_1 - phi_0")
    ds.attrs.update(title="closed-loop pairs: phase locking", channel_width_m=PAIR_CHANNEL_M,
                    duration_s=p["duration_s"], phase_oscillator_coupling=PAIR_COUPLING)
    summary = _pair_summary(ds)
    summary.update(n_failed=len(res.failures), failures=[str(f) for f in res.failures[:20]],
                   sweep_elapsed_s=float(res.elapsed_s))
    summary["claims"] = pair_claims(summary)
    return StudyResult(dataset=ds, figure=plot_sync_pairs(ds), summary=summary)


@register("synchronization-groups", paper_figure=None,
          description="3-10 closed-loop swimmers, phases and positions free: order parameter R(t), time to "
                      "lock, and whether the final state is phase-locked, position-compatible, or both.")
def run_groups(config: StudyConfig) -> StudyResult:
    from ..plotting.synchronization import plot_sync_groups
    from ..sweep import Grid, run_sweep

    p = group_plan(config.quick)
    grid = Grid(axes={"controller": list(CONTROLLERS), "n_swimmers": p["n_swimmers"], "spacing_m": p["spacing_m"]},
                replicates=p["replicates"], seed=config.seed)
    fn = functools.partial(group_run, duration_s=p["duration_s"])
    res = run_sweep(fn, grid, _sweep_dir(config, "synchronization-groups"), scheduler=config.scheduler)
    ds = _label(res.dataset)
    ds["spacing_m"].attrs.update(units="m", long_name="channel width per swimmer")
    ds["n_swimmers"].attrs.update(units="1")
    ds.attrs.update(title="closed-loop groups: phase and position free", duration_s=p["duration_s"],
                    phase_oscillator_coupling=PAIR_COUPLING)
    per = {}
    for c in ds["controller"].values:
        v = ds.sel(controller=c)
        ok = np.isfinite(v["R_final"].values)
        locked = v["phase_locked"].values.astype(bool) & ok
        compat = (v["compat_rms"].values < COMPAT_TOL) & ok
        per[str(c)] = {"n_runs": int(ok.sum()), "phase_locked": int(locked.sum()), "compatible": int(compat.sum()),
                       "free_frequency_hz": free_frequency_hz(str(c)),
                       "median_collective_frequency_hz": float(np.nanmedian(v["frequency"].values)),
                       "both": int((locked & compat).sum()),
                       "median_R_final": float(np.nanmedian(v["R_final"].values)),
                       "median_lock_time_s": float(np.nanmedian(v["lock_time"].values))
                       if np.isfinite(v["lock_time"].values).any() else float("nan")}
    summary: dict[str, Any] = {"per_controller": per, "n_failed": len(res.failures),
                               "failures": [str(f) for f in res.failures[:20]],
                               "sweep_elapsed_s": float(res.elapsed_s)}
    summary["claims"] = group_claims(summary)
    return StudyResult(dataset=ds, figure=plot_sync_groups(ds), summary=summary)
