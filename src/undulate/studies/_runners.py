"""The three runners every simulation study uses (sweep functions ``fn(point, seed) -> Dataset``).

* :func:`group_point` -- ``n`` swimmers side by side from straight, laterally
  in contact, at ``dx0 = 0`` (the pair, link-number and group studies; a
  pair is a group of two): their centres, phases, contact force and joint
  error over time.
* :func:`pair_point` -- two swimmers from a given offset ``dx0``, in a channel
  set in metres or in ``d/2A``, with equal and opposite forces or the
  swimming ground (basins, confinement, potential, swimming): ``dx(t)`` and
  its steady value, contact impulse, speed.
* :func:`lone_swimmer` -- one free swimmer: the gait amplitude ``A`` (the one
  definition every study uses, through ``StudyContext.lone_swimmer``), its
  joint error and speed.

Every constant a runner reads is a module constant here or a default
argument: both are part of a sweep's identity (the code hash covers this
file, the bound call every default), so changing one recomputes the runs.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import xarray as xr

from ..errors import ParameterError
from ..params import Channel, Scene, SimOptions, SwimmerGeometry
from ..stopping import PhaseStop, SteadyStop
from .. import theory
from ._criteria import PAIR_CHANNEL_M, STEADY_TOL, STEADY_WINDOW
from ._points import GroupPoint, LonePoint, PairPoint

__all__ = ["BODY_LENGTH_M", "PERIOD_S", "DURATION_S", "SAMPLE_RATE_HZ", "TIMESTEP_S", 
           "PAIR_DURATION_S", "RECORD_HZ", "LONE_DURATION_S", "LONE_CHANNEL_WIDTH_M",
           "AMPLITUDE_ROUND_M", "PAIR_STOP", "round_amplitude", "group_point", "pair_scene", "pair_point", "lone_swimmer"]

BODY_LENGTH_M = 0.54
"""L, m (the paper's robots; the SwimmerGeometry default)."""
PERIOD_S = 2.0
"""Gait period 1/f at the default f = 0.5 Hz, s."""
DURATION_S = 30.0
"""15 gait periods, as the paper's runs, s."""
SAMPLE_RATE_HZ = 10.0
"""Recording rate of the group runs, Hz (20 samples per period)."""
TIMESTEP_S = 0.002
"""Integrator step of the 3-link group runs, s (other link numbers give ``timestep_s`` in the point)."""

PAIR_DURATION_S = 30.0
"""Pair runs last 15 gait periods, s (the paper's experiments)."""
RECORD_HZ = 5.0
"""Rate at which a pair run keeps dx(t), Hz."""

LONE_DURATION_S = 30.0
"""Length of a free swimmer's run, s (15 periods: its speed is fitted over the second half)."""
LONE_CHANNEL_WIDTH_M = 1.0
"""Channel width for the free swimmer, m: far wider than its stroke."""
LONE_PERIODS = 3
"""A is measured over the last LONE_PERIODS whole periods."""
LONE_SKIP_S = 2.0
"""The free swimmer's joint error is averaged over t >= LONE_SKIP_S (one period), s."""
PAIR_STOP = SteadyStop(tol=STEADY_TOL, window=3, extra_periods=2, min_periods=6, drift_frac=0.5,
                       spread_frac=0.5)
"""The pair-type studies' stopping rule (bound as ``stop=`` by the studies that use it; the runners'
default ``None`` runs the whole duration): the steady rule, with half its tolerance as a margin, held
for 2 more periods, never before 6 periods, and no trend that would carry the offsets more than half
the tolerance by the run's end."""
AMPLITUDE_ROUND_M = 1e-5
"""Measured amplitudes are rounded to this (m) before they set channel widths, so a
resumed sweep finds the same parameters after a bitwise-different re-measurement."""


def _simulate_stopped(scene: Scene, options: SimOptions, stop: SteadyStop | PhaseStop | None):
    """``simulate`` with a pair-type stopping rule (:data:`PAIR_STOP`, a closed-loop
    :class:`~undulate.stopping.PhaseStop`; None: the whole duration); also the number of samples the
    full-length run records (a stopped run's series are padded with NaN to it)."""
    dss, n_full = _simulate_stopped_batch([scene], options, stop)
    return dss[0], n_full


def _simulate_stopped_batch(scenes: list[Scene], options: SimOptions, stop: SteadyStop | PhaseStop | None):
    """:func:`_simulate_stopped` for scenes of one structure (and closed-loop controller) stepped
    together, each with its own monitor of ``stop`` (its period and length scale): each Dataset is
    bitwise its scene's run alone (:func:`undulate.simulation.simulate_batch`)."""
    from ..simulation import resolve_options, simulate_batch

    monitors = None
    if stop is not None:
        monitors = [stop.monitor(sc.gait.period_s, sc.wavelength_m if math.isfinite(sc.wavelength_m)
                                 else sc.geometry.length_m, options.duration_s) for sc in scenes]
    dss = simulate_batch(scenes, options, stop=monitors)
    full = resolve_options(scenes[0], options)
    return dss, full.n_steps // full.steps_per_sample + 1


def _in_batches(keys: list, run) -> list:
    """A batched sweep function's results in its points' order: ``run(key, idx)`` steps the points
    ``idx`` that share ``key`` (one batch: same controller, structure) and returns their results."""
    out: list = [None] * len(keys)
    for key in dict.fromkeys(keys):
        idx = [i for i, k in enumerate(keys) if k == key]
        for i, res in zip(idx, run(key, idx)):
            out[i] = res
    return out


def _padded(values: np.ndarray, n: int) -> np.ndarray:
    """``values`` (time first) padded with NaN to ``n`` samples."""
    v = np.asarray(values, float)
    out = np.full((n, *v.shape[1:]), np.nan)
    out[:len(v)] = v
    return out


def _stop_vars(ds: xr.Dataset) -> dict:
    return {"stopped_at_s": ((), float(ds.attrs["stopped_at"]), {
        "units": "s", "long_name": "last sample (the duration unless the stopping rule ended the run; "
                                   "the series are NaN after it)", "stop_rule": ds.attrs["stop_rule"] or "none"})}


def round_amplitude(a_m: float) -> float:
    """A measured amplitude (m) rounded to :data:`AMPLITUDE_ROUND_M`."""
    return float(round(a_m / AMPLITUDE_ROUND_M) * AMPLITUDE_ROUND_M)


def group_point(point: dict[str, Any], seed: int, *, n_swimmers: int = 2, channel_width_m: float = PAIR_CHANNEL_M,
                   random_phases: bool = False, duration_s: float = DURATION_S,
                   sample_rate_hz: float = SAMPLE_RATE_HZ, stop: SteadyStop | None = None) -> xr.Dataset:
    """Simulate one scene of a study grid; a small Dataset for the sweep store.

    ``point`` keys (all optional): ``dphi_rad`` (phase step between
    neighbours in the initial stack, rad: swimmer ``j`` gets ``j dphi``;
    default 0), ``waves_per_body`` (xi, default 1), ``n_links`` (default 3),
    ``amplitude_rad`` (beta, default 45 degrees), ``timestep_s`` (default
    :data:`TIMESTEP_S`) and any of :data:`MODEL_KEYS` (servo ``kp``, torque
    limit, top speed; contact time constant, s; linear drag per link, N s/m).  With ``random_phases`` every swimmer's phase is
    drawn uniformly from ``[0, 2 pi)`` with ``numpy.random.default_rng(seed)``
    (the sweep's per-run seed) and ``dphi_rad`` is ignored.  Swimmers start
    straight, laterally in contact, at dx0 = 0 (paper Methods).

    Returns (dims; units): ``x``, ``y`` (time, swimmer; m) centres of mass,
    ``phase`` (swimmer; rad), ``joint_error`` (time, swimmer; rad, mean over
    the joints), ``contact_force_pair`` (time, pair; N, swimmers p and p+1
    of the initial stack), ``penetration_max`` (m), the wavelength
    ``wavelength`` (m, inf for xi = 0) and ``extent_x`` (swimmer; m), the
    head-to-tail extent along x averaged over the second half of the run (for
    xi waves per body, xi times the wavelength along the channel).
    ``heading_guide`` (bool, default False): :attr:`~undulate.params.Scene.heading_guide`.
    ``stop``: a stopping rule (e.g. :data:`PAIR_STOP`; None: the whole ``duration_s``): the series
    then end at ``stopped_at_s`` (NaN after it, on the full run's time axis), and ``extent_x`` and
    ``penetration_max`` are over the run as stepped.
    """
    pt = GroupPoint.of(point)
    n_links = pt.n_links
    dt = TIMESTEP_S if pt.timestep_s is None else pt.timestep_s
    if random_phases:
        phases = tuple(np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, n_swimmers))
    else:
        phases = tuple(j * pt.dphi_rad for j in range(n_swimmers))
    scene = Scene(
        phases_rad=phases,
        gait=pt.gait(),
        geometry=SwimmerGeometry(n_links=n_links, length_m=BODY_LENGTH_M),
        channel=Channel(width_m=channel_width_m),
        heading_guide=pt.heading_guide,
        **pt.model_parts(),
    )
    ds, n_full = _simulate_stopped(scene, SimOptions(duration_s=duration_s, timestep_s=dt,
                                                     sample_rate_hz=sample_rate_hz), stop)
    time = ds["time"].values
    nx = ds["node_x"].values[time >= time[-1] / 2]
    extent = np.abs(nx[..., -1] - nx[..., 0]).mean(axis=0)
    time = np.round(np.arange(n_full) * float(ds.attrs["sample_interval"]), 12)  # the full run's axis
    return xr.Dataset(
        {
            "x": (("time", "swimmer"), _padded(ds["x"].values, n_full), {"units": "m", "long_name": "centre of mass x"}),
            "y": (("time", "swimmer"), _padded(ds["y"].values, n_full), {"units": "m", "long_name": "centre of mass y"}),
            "phase": ("swimmer", np.asarray(phases, float), {"units": "rad", "long_name": "gait phase phi"}),
            "joint_error": (("time", "swimmer"), _padded(ds["joint_error"].values.mean(axis=-1), n_full),
                            {"units": "rad", "long_name": "joint error |alpha - alpha_cmd|, mean over joints"}),
            "contact_force_pair": (("time", "pair"), _padded(ds["contact_force_pair"].values, n_full),
                                   {"units": "N", "long_name": "net contact force between swimmers pair "
                                                               "and pair+1 of the initial stack"}),
            "penetration_max": ((), float(ds["penetration"].max()), {"units": "m"}),
            "wavelength": ((), float(ds.attrs["wavelength"]), {"units": "m"}),
            "extent_x": ("swimmer", extent, {"units": "m", "long_name": "head-to-tail extent along x, "
                                                                        "mean over the second half of the run"}),
            **_stop_vars(ds),
        },
        coords={"time": ("time", time, {"units": "s"})},
    )


def pair_scene(point: dict, *, amplitude_m: float | None = None, force_onset_s: float = 0.0,
               force_offset_s: float | None = None) -> Scene:
    """The pair scene of a sweep point.

    Keys (all optional): ``dx0_over_lambda`` (initial x_b - x_a over lambda;
    0), ``dphi_rad`` (phi_b - phi_a, rad; 0), ``phi0_rad`` (phase of swimmer
    a, rad; 0), ``channel_width_m`` (W, wall to wall, m; 0.13) or ``d_over_2A`` (the
    paper's confinement: the wall distance per swimmer over twice the gait amplitude,
    given by the key ``amplitude_m`` (m) or else the keyword ``amplitude_m``; the channel
    is :func:`undulate.theory.channel_width_m` for two swimmers, ``W = 2 (d/2A) 2A``),
    ``amplitude_rad`` (beta, rad; 45 degrees), ``waves_per_body`` (xi; 1),
    ``force_N`` (dF, N: swimmer a is pushed toward -x and b toward +x, from
    ``force_onset_s`` until ``force_offset_s``, None: to the end; 0), ``ground`` (``"viscous"``;
    ``"resistive"``: :meth:`Ground.resistive`, with ``drag_N_s_per_m`` its c_par if given; or ``"swimming"``),
    ``body_width_m`` (w of every link, m; the SwimmerGeometry default),
    ``fluid_density_kg_m3`` (the swimming ground's fluid density, kg/m^3:
    the strength of its anisotropic drag; :meth:`Ground.swimming`'s default),
    ``swim_drag_N_s_per_m`` (the swimming ground's linear drag per link, N s/m;
    :meth:`Ground.swimming`'s default), ``drag_N_s_per_m`` (the viscous
    ground's linear drag per link, N s/m; :class:`Ground`'s default).
    """
    pt = PairPoint.of(point)
    gait, geo = pt.gait(), pt.geometry()
    lam = gait.wavelength_m(geo.length_m)
    if pt.d_over_2A is not None:
        amp = pt.amplitude_m if pt.amplitude_m is not None else amplitude_m
        if amp is None:
            raise ParameterError("d_over_2A", "given with an amplitude (the point's amplitude_m or the "
                                 "keyword amplitude_m)", pt.d_over_2A)
        width = float(theory.channel_width_m(pt.d_over_2A, float(amp), n_swimmers=2))
    else:
        width = PAIR_CHANNEL_M if pt.channel_width_m is None else pt.channel_width_m
    f = pt.force_N
    return Scene(
        phases_rad=(pt.phi0_rad, pt.phi0_rad + pt.dphi_rad),
        gait=gait,
        geometry=geo,
        ground=pt.ground_model(),
        channel=Channel(width_m=width),
        dx0_m=pt.dx0_over_lambda * lam,
        forces_N=(-f, f) if f else None,
        force_onset_s=float(force_onset_s) if f else 0.0,
        force_offset_s=force_offset_s if f else None,
    )


def pair_point(point: dict, seed: int, *, duration_s: float = PAIR_DURATION_S,
               amplitude_m: float | None = None, force_onset_s: float = 0.0,
               force_offset_s: float | None = None, record_hz: float = RECORD_HZ, stop: SteadyStop | None = None):
    """One pair run (sweep function): the offsets over time and their summary.

    ``point``: see :func:`pair_scene`.  Returns (``dx = x_1 - x_0``, swimmer
    1 the one that starts above, with phase ``dphi``; ``swapped_sides`` flags
    a run in which the two changed lateral order at some time, which in the
    lateral-order convention flips the signs of dx and dphi together):
    ``dx_over_lambda(time)`` at ``record_hz``;
    ``dx_period_over_lambda(period_time)`` (whole-period means);
    ``dx_final_over_lambda`` (mean of the last 3 periods), ``steady``
    (``observables.steady_state``, tolerance :data:`STEADY_TOL`),
    ``settle_time_s`` (a run shorter than :data:`STEADY_WINDOW` periods: NaN, not steady, NaN);
    ``dy_final_m``; ``impulse_2T_Ns`` (swimmer-swimmer contact impulse over the first two periods:
    a run of two periods, :data:`._shared.IMPULSE_DURATION_S`, has it all); ``mean_joint_error_rad``
    (t >= one period); ``speed_m_s`` (the pair's mean speed toward -x over
    the last 3 periods); ``max_penetration_m``.  ``seed`` is unused.
    ``stop``: a stopping rule (e.g. :data:`PAIR_STOP`; None: the whole ``duration_s``, which is
    also the default).  Every scalar is then computed on the run as stepped, the same way (the
    last 3 periods are those before ``stopped_at_s``; the joint error and penetration over it);
    the two series are NaN after it, on the full run's axes.
    """
    import xarray as xr

    from ..observables import contact_impulse, neighbour_offsets, period_average, steady_state

    scene = pair_scene(point, amplitude_m=amplitude_m, force_onset_s=force_onset_s, force_offset_s=force_offset_s)
    ds, n_full = _simulate_stopped(scene, SimOptions(duration_s=duration_s), stop)
    lam = scene.wavelength_m
    T = scene.gait.period_s
    # dx = x_1 - x_0 and dy = y_1 - y_0 in the initial labels (swimmer 1 starts above
    # swimmer 0 and has phase dphi): the lateral-order convention as long as the two
    # do not swap sides, and the same physics (dx, dphi -> -dx, -dphi) if they do.
    off = neighbour_offsets(ds).isel(pair=0)
    sign = xr.where(off["lower"] == 0, 1.0, -1.0)
    swapped = bool((sign < 0).any())
    off = off.assign(dx=off["dx"] * sign, dy=off["dy"] * sign)
    dxl = off["dx"] / lam
    pa = period_average(dxl, T)
    if pa.sizes["time"] >= STEADY_WINDOW:
        st = steady_state(dxl, T, tol=STEADY_TOL, window=STEADY_WINDOW)
    else:  # a run shorter than the steady window (e.g. the two-period impulse runs): no steady value
        st = {"value": math.nan, "steady": False, "settle_time": math.nan}
    dy = period_average(off["dy"], T)
    xc = period_average(ds["x"].mean("swimmer"), T).values
    every = max(1, int(round(1.0 / (record_hz * float(ds.attrs["sample_interval"])))))
    rec = dxl.isel(time=slice(0, None, every))
    imp = float(contact_impulse(ds, 0.0, 2 * T)["pair"].isel(pair=0))
    je = float(ds["joint_error"].where(ds["time"] >= T).mean())
    one = {"units": "1"}
    si = float(ds.attrs["sample_interval"])
    t_rec = np.round(np.arange(0, n_full, every) * si, 12)
    t_per = (np.arange(int(np.floor((n_full - 1) * si / T + 1e-9))) + 0.5) * T
    return xr.Dataset(
        {
            "dx_over_lambda": (("time",), _padded(rec.values, len(t_rec)), {**one, "long_name": "dx / lambda"}),
            "dx_period_over_lambda": (("period_time",), _padded(pa.values, len(t_per)),
                                      {**one, "long_name": "period mean of dx / lambda"}),
            "dx_final_over_lambda": ((), float(st["value"]), {**one, "long_name": "final dx / lambda (last 3 periods)"}),
            "steady": ((), bool(st["steady"])),
            "settle_time_s": ((), float(st["settle_time"]), {"units": "s"}),
            "dy_final_m": ((), float(dy.values[-3:].mean()), {"units": "m", "long_name": "final dy"}),
            "impulse_2T_Ns": ((), imp, {"units": "N s", "long_name": "pair contact impulse over the first 2 periods"}),
            "mean_joint_error_rad": ((), je, {"units": "rad"}),
            "speed_m_s": ((), float((xc[-4] - xc[-1]) / (3 * T)) if xc.size >= 4 else float("nan"),
                          {"units": "m/s", "long_name": "pair speed toward -x, last 3 periods"}),
            "max_penetration_m": ((), float(ds["penetration"].max()), {"units": "m"}),
            "swapped_sides": ((), swapped),
            **_stop_vars(ds),
        },
        coords={
            "time": ("time", t_rec, {"units": "s"}),
            "period_time": ("period_time", t_per, {"units": "s"}),
        },
    )


def lone_swimmer(point: dict, seed: int, *, duration_s: float = LONE_DURATION_S) -> xr.Dataset:
    """One free swimmer (sweep function): the gait amplitude A, joint error and speed.

    ``point``: ``amplitude_rad`` (beta, rad; 45 degrees), ``waves_per_body``
    (xi; 1), ``n_links`` (3), ``ground`` (``"viscous"``, ``"resistive"``,
    :meth:`Ground.resistive`, or ``"swimming"``, :meth:`Ground.swimming`), ``heading_guide`` (False; :attr:`Scene.heading_guide`).  One swimmer in a :data:`LONE_CHANNEL_WIDTH_M`
    wide channel for ``duration_s`` at the simulator's time step.  Returns
    ``amplitude_m`` (A: :func:`~undulate.observables.gait_amplitude` over the
    last :data:`LONE_PERIODS` periods, rounded to :data:`AMPLITUDE_ROUND_M`),
    ``mean_joint_error_rad`` (mean over joints and t >= :data:`LONE_SKIP_S`),
    ``speed_m_s`` (toward -x: straight-line fit of the period-averaged centre
    x over the second half of the run) and ``x_period_m`` (period-averaged
    centre x).  Deterministic (``seed`` unused).
    """
    from ..observables import gait_amplitude, period_average
    from ..simulation import simulate

    pt = LonePoint.of(point)
    gait = pt.gait()
    g = pt.ground_model()
    scene = Scene(phases_rad=(0.0,), gait=gait, ground=g,
                  geometry=SwimmerGeometry(n_links=pt.n_links, length_m=BODY_LENGTH_M),
                  channel=Channel(width_m=LONE_CHANNEL_WIDTH_M), heading_guide=pt.heading_guide)
    ds = simulate(scene, SimOptions(duration_s=duration_s, sample_rate_hz=50.0))
    period = scene.gait.period_s
    amp = round_amplitude(gait_amplitude(ds, periods=LONE_PERIODS))
    je = float(ds["joint_error"].where(ds["time"] >= LONE_SKIP_S).mean())
    xp = period_average(ds["x"].isel(swimmer=0), period)
    half = xp.sizes["time"] // 2
    tt, xx = xp["time"].values[half:], xp.values[half:]
    speed = -float(np.polyfit(tt, xx, 1)[0]) if len(tt) >= 2 else float("nan")
    return xr.Dataset(
        {
            "amplitude_m": ((), amp, {"units": "m", "long_name": "gait amplitude A of a free swimmer"}),
            "mean_joint_error_rad": ((), je, {"units": "rad", "long_name": "mean joint error, free swimmer"}),
            "speed_m_s": ((), speed, {"units": "m/s", "long_name": "forward speed toward -x"}),
            "x_period_m": (("period_time",), xp.values, {"units": "m", "long_name": "period-averaged centre x"}),
        },
        coords={"period_time": ("period_time", xp["time"].values, {"units": "s"})},
    )
