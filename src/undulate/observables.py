"""Observables: pure functions of a recorded trajectory (an ``xarray.Dataset``
from :func:`undulate.simulate`).  No hidden state; they serve the tests, the
studies and a user's notebook alike.  Each checks its arguments first: a
bad one (a period that is not > 0 s, a swimmer the record does not hold, a
mean force over no time) raises :class:`~undulate.errors.ParameterError`
naming it and what is allowed.

Conventions: neighbours are identified by **lateral order** at every sample
(sorted by centre-of-mass ``y``); for the neighbouring ranks ``r`` (lower)
and ``r+1`` (upper), ``dx = x_upper - x_lower``, ``dy = y_upper - y_lower``
and ``dphi = phi_upper - phi_lower`` wrapped into ``(-pi, pi]``.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import xarray as xr

from .errors import ParameterError
from .params import _count, _finite, _nonneg, _positive
from .theory import wrap_phase

__all__ = [
    "lateral_ranks",
    "lateral_order",
    "neighbour_offsets",
    "dx_over_wavelength",
    "period_average",
    "steady_state",
    "centreline_points",
    "gait_amplitude",
    "contact_impulse",
    "mean_contact_force",
    "wrap_angle",
    "middle_link_pose",
]


wrap_angle = wrap_phase
"""Wrap angles (rad) into (-pi, pi] (a phase difference of pi reads +pi):
:func:`undulate.theory.wrap_phase`, the package's one convention, under the name
the observables have always used."""


def _trajectory(ds, variables: tuple[str, ...] = (), attrs: tuple[str, ...] = (), timed: bool = True) -> xr.Dataset:
    """``ds`` if it is a recorded trajectory holding ``variables`` (data or coordinates) and ``attrs``
    (and, if ``timed``, over a ``time`` of increasing samples); else a ParameterError naming ``ds``."""
    what = "a recorded trajectory (an xarray.Dataset from undulate.simulate)"
    if not isinstance(ds, xr.Dataset):
        raise ParameterError("ds", what, type(ds).__name__)
    lacks = [v for v in variables if v not in ds.variables] + [f"attrs[{a!r}]" for a in attrs if a not in ds.attrs]
    if lacks:
        raise ParameterError("ds", f"{what} with {', '.join(variables + tuple(f'attrs[{a!r}]' for a in attrs))}; "
                                   f"it lacks {', '.join(lacks)}")
    if timed:
        _times(ds, "ds")
    return ds


def _times(obj, name: str) -> np.ndarray:
    """The ``time`` coordinate of ``obj``: finite samples, strictly increasing, s."""
    if "time" not in obj.dims or "time" not in obj.coords:
        raise ParameterError(name, "data over a 'time' coordinate (s)", f"dims {tuple(obj.dims)}")
    t = np.asarray(obj["time"].values)
    if t.dtype.kind not in "fiu" or t.size < 1 or not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
        raise ParameterError(name, "data over finite, strictly increasing times (s)",
                             f"{t.size} time(s) of dtype {t.dtype}")
    return t


def _running_mean(a: np.ndarray, n: int) -> np.ndarray:
    """Running mean over ``n`` samples along axis 0, centred where possible:
    near the ends the full window slides inside the record instead of shrinking."""
    n = min(n, a.shape[0])
    if n <= 1:
        return a
    c = np.cumsum(np.concatenate([np.zeros((1,) + a.shape[1:]), a]), axis=0)
    i = np.arange(a.shape[0])
    lo = np.clip(i - n // 2, 0, a.shape[0] - n)
    hi = lo + n
    return (c[hi] - c[lo]) / (hi - lo)[:, None]


def lateral_ranks(y) -> np.ndarray:
    """Swimmer ids from the lowest to the highest ``y`` along the last axis (ties keep id order).

    The package's one rule for lateral neighbours: ranks ``r`` and ``r + 1`` are
    neighbours, ``r`` the lower.  What ``y`` is averaged over before ranking is the
    caller's: one gait period around each sample (:func:`lateral_order`) or the
    steady-state window at the end of a run
    (:func:`undulate.studies._analysis.final_neighbours`).
    """
    return np.argsort(np.asarray(y), axis=-1, kind="stable")


def lateral_order(ds: xr.Dataset, window_s: float | None = None) -> xr.DataArray:
    """Swimmer ids sorted by lateral position at each sample: (time, rank).

    Swimmers are ordered by their centre-of-mass ``y`` averaged over a
    centred window of ``window_s`` (default: one gait period, from
    ``ds.attrs["period"]``).  Undulating bodies in close contact can swap
    the order of their instantaneous centres within a cycle while keeping
    their lateral places; the window removes that flicker.  A real swap of
    lateral places, lasting longer than the window, is followed.
    ``window_s = 0`` orders by the instantaneous ``y``.
    """
    _trajectory(ds, ("y",))
    if window_s is None:
        window_s = float(ds.attrs.get("period", 0.0))
    window_s = _nonneg("window_s", window_s, "s")
    y = ds["y"].values
    t = ds["time"].values
    dt = float(t[1] - t[0]) if len(t) > 1 else 1.0
    n = max(1, int(round(window_s / dt)))
    order = lateral_ranks(_running_mean(y, n))
    return xr.DataArray(order, dims=("time", "rank"), coords={"time": ds["time"]},
                        attrs={"long_name": "swimmer id at lateral rank (0 = lowest y)",
                               "window_s": window_s})


def neighbour_offsets(ds: xr.Dataset, window_s: float | None = None) -> xr.Dataset:
    """Nearest-neighbour offsets by lateral order (see :func:`lateral_order`).

    Returns a Dataset with dims ``(time, pair)`` (pair ``r`` joins ranks
    ``r`` and ``r+1``): ``dx`` and ``dy`` in m, ``dphi`` in rad, and the
    swimmer ids ``lower`` and ``upper``.
    """
    _trajectory(ds, ("x", "y", "phase"), ("wavelength",))
    order = lateral_order(ds, window_s).values
    x, y = ds["x"].values, ds["y"].values
    phase = np.asarray(ds["phase"].values, dtype=float)
    lo, hi = order[:, :-1], order[:, 1:]
    take = np.take_along_axis
    dx = take(x, hi, axis=1) - take(x, lo, axis=1)
    dy = take(y, hi, axis=1) - take(y, lo, axis=1)
    dphi = wrap_angle(phase[hi] - phase[lo])
    dims = ("time", "pair")
    return xr.Dataset(
        {
            "dx": (dims, dx, {"units": "m", "long_name": "longitudinal offset x_upper - x_lower"}),
            "dy": (dims, dy, {"units": "m", "long_name": "lateral offset y_upper - y_lower"}),
            "dphi": (dims, dphi, {"units": "rad", "long_name": "phase difference phi_upper - phi_lower"}),
            "lower": (dims, lo),
            "upper": (dims, hi),
        },
        coords={"time": ds["time"], "pair": np.arange(lo.shape[1])},
        attrs={"wavelength": ds.attrs["wavelength"], "wavelength_units": "m"},
    )


def dx_over_wavelength(ds: xr.Dataset) -> xr.DataArray:
    """Nearest-neighbour ``dx / lambda`` (time, pair), dimensionless.

    For the standing wave (lambda = inf) this is identically 0; use ``dx`` in
    metres there.
    """
    off = neighbour_offsets(ds)
    lam = float(ds.attrs["wavelength"])
    out = off["dx"] / lam
    out.attrs = {"units": "1", "long_name": "dx / lambda"}
    return out


def period_average(da: xr.DataArray, period_s: float) -> xr.DataArray:
    """Average over whole gait periods counted from the first sample.

    Period ``k`` holds the samples with ``t`` in ``(t0 + kT, t0 + (k+1)T]``
    (the same half-open intervals the recorded force means use); the first
    sample itself starts the clock and is not averaged.  The result has one
    value per complete period, its ``time`` coordinate at the period's
    midpoint; an incomplete last period is dropped.
    """
    if not isinstance(da, xr.DataArray):
        raise ParameterError("da", "an xarray.DataArray over a 'time' coordinate (s)", type(da).__name__)
    t = _times(da, "da")
    period_s = _positive("period_s", period_s, "s")
    u = (t - t[0]) / period_s
    k = np.ceil(u - 1e-9).astype(int) - 1
    n_full = int(np.floor(u[-1] + 1e-9))
    if n_full < 1:
        raise ValueError("period_average needs at least one whole period of data")
    ax = da.get_axis_num("time")
    keep = np.flatnonzero((k >= 0) & (k < n_full))
    vals = np.asarray(da.values)[(slice(None),) * ax + (keep,)]  # the whole periods' samples (a copy)
    edges = np.searchsorted(k[keep], np.arange(n_full + 1))  # k rises with t: each period is one slice
    # per period, the NaN-skipping mean over its slice: what xarray's ``groupby("period").mean("time")``
    # computes, bitwise (tested), at a fraction of its overhead (pair runs average over ~30 periods often)
    mean = np.nanmean if vals.dtype.kind in "fc" else np.mean
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN period is NaN, as in xarray
        means = [mean(vals[(slice(None),) * ax + (slice(edges[i], edges[i + 1]),)], axis=ax)
                 for i in range(n_full)]
    data = np.stack(means, axis=ax)
    coords = {name: c for name, c in da.coords.items() if "time" not in c.dims}
    coords["time"] = ("time", t[0] + (np.arange(n_full) + 0.5) * period_s)
    return xr.DataArray(data, dims=da.dims, coords=coords, name=da.name, attrs=dict(da.attrs))


def period_average_groupby(da: xr.DataArray, period_s: float) -> xr.DataArray:
    """:func:`period_average` as xarray's ``groupby("period").mean("time")`` computes it: the reference
    the fast path is checked against (bitwise, ``tests/test_observables.py``) and timed against
    (``benchmarks/bench_overheads.py``).  Not used by the package itself."""
    t = da["time"].values
    u = (t - t[0]) / period_s
    k = np.ceil(u - 1e-9).astype(int) - 1
    n_full = int(np.floor(u[-1] + 1e-9))
    keep = (k >= 0) & (k < n_full)
    g = da.isel(time=np.flatnonzero(keep)).assign_coords(period=("time", k[keep]))
    out = g.groupby("period").mean("time")
    out = out.assign_coords(time=("period", t[0] + (np.arange(n_full) + 0.5) * period_s))
    out = out.swap_dims({"period": "time"}).drop_vars("period")
    out.attrs = dict(da.attrs)
    return out


def steady_state(da: xr.DataArray, period_s: float, tol: float, window: int = 3) -> xr.Dataset:
    """Steady value of a slowly settling signal (e.g. Δx/λ), per pair.

    Rule: average over whole periods; the signal is *steady* once the
    period averages of the last ``window`` periods all lie within ``tol`` of
    their mean (same units as ``da``).  The steady value is that mean; the
    settle time is the start of the earliest period from which every later
    window of ``window`` periods satisfies the same bound.  If the last
    window does not satisfy it, ``steady`` is False and ``value`` is still
    the last-window mean (reported, flagged).

    Returns a Dataset with ``value``, ``steady`` (bool), ``settle_time``
    (s, NaN if never), ``spread`` (max deviation in the last window) over
    the non-time dims of ``da``.
    """
    tol = _nonneg("tol", tol)
    window = _count("window", window, 1)
    pa = period_average(da, period_s)
    n = pa.sizes["time"]
    if n < window:
        raise ValueError(f"steady_state needs at least {window} whole periods, got {n}")
    a = pa.transpose("time", ...).values
    a2 = a.reshape(n, -1)
    # windowed max deviation from the window mean
    dev = np.empty((n - window + 1, a2.shape[1]))
    means = np.empty_like(dev)
    for i in range(n - window + 1):
        w = a2[i:i + window]
        means[i] = w.mean(axis=0)
        dev[i] = np.abs(w - means[i]).max(axis=0)
    ok = dev <= tol
    last = ok[-1]
    # earliest i such that ok[i:] all true
    settle = np.full(a2.shape[1], np.nan)
    for c in range(a2.shape[1]):
        if last[c]:
            bad = np.flatnonzero(~ok[:, c])
            first = 0 if bad.size == 0 else bad[-1] + 1
            settle[c] = float(pa["time"].values[first]) - period_s / 2
    shape = a.shape[1:]
    dims = tuple(d for d in pa.dims if d != "time")
    coords = {d: pa[d] for d in dims if d in pa.coords}
    return xr.Dataset(
        {
            "value": (dims, means[-1].reshape(shape), dict(da.attrs)),
            "steady": (dims, last.reshape(shape)),
            "settle_time": (dims, settle.reshape(shape), {"units": "s"}),
            "spread": (dims, dev[-1].reshape(shape), dict(da.attrs)),
        },
        coords=coords,
        attrs={"rule": f"period averages of the last {window} periods within {tol:g} of their mean",
               "period_s": period_s, "tol": tol, "window": window},
    )


def centreline_points(ds: xr.Dataset, per_link: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """Points along every swimmer's centre line: arrays (time, swimmer, point), m.

    Interpolates ``per_link`` points on each link between recorded nodes.
    """
    _trajectory(ds, ("node_x", "node_y"), timed=False)  # geometry, sample by sample
    per_link = _count("per_link", per_link, 1)
    nx, ny = ds["node_x"].values, ds["node_y"].values
    s = np.linspace(0.0, 1.0, per_link, endpoint=False)
    px = nx[..., :-1, None] + (nx[..., 1:, None] - nx[..., :-1, None]) * s
    py = ny[..., :-1, None] + (ny[..., 1:, None] - ny[..., :-1, None]) * s
    sh = px.shape[:-2] + (-1,)
    px = np.concatenate([px.reshape(sh), nx[..., -1:]], axis=-1)
    py = np.concatenate([py.reshape(sh), ny[..., -1:]], axis=-1)
    return px, py


def gait_amplitude(ds: xr.Dataset, swimmer: int = 0, periods: int = 1) -> float:
    """Gait amplitude A of a free swimmer, m, from its kinematics.

    A is half the peak-to-peak lateral extent of the body's centre line over
    the last ``periods`` whole gait periods: the centre line is expressed in
    the frame of the swimmer's mean position and mean heading over that
    window, and A = (max y' - min y') / 2 over all body points and times.
    """
    _trajectory(ds, ("node_x", "node_y", "heading"), ("period",))
    swimmer = _count("swimmer", swimmer, 0, ds.sizes.get("swimmer", 1) - 1)
    periods = _count("periods", periods, 1)
    period = float(ds.attrs["period"])
    t = ds["time"].values
    t_end = t[-1]
    sel = t >= t_end - periods * period - 1e-9
    if t_end - t[0] < periods * period - 1e-9:
        raise ValueError("gait_amplitude needs at least `periods` whole periods of data")
    px, py = centreline_points(ds.isel(time=np.flatnonzero(sel), swimmer=[swimmer]))
    px, py = px[:, 0], py[:, 0]
    cx, cy = px.mean(), py.mean()
    h = float(ds["heading"].values[sel, swimmer].mean())
    # body axis direction (head toward -x at heading 0): axis angle = heading
    yp = -(px - cx) * math.sin(h) + (py - cy) * math.cos(h)
    return float((yp.max() - yp.min()) / 2)


def _interval(ds, t_from, t_to, empty: bool = True) -> tuple[float, float | None]:
    """``t_from`` and ``t_to`` (s) of a contact-force integral over ``ds``, checked: finite, ``t_to`` (None:
    the last sample) not before ``t_from``, nor at it unless ``empty`` allows an interval of no time."""
    _trajectory(ds, ("contact_force_pair", "contact_force_wall"), ("sample_interval",))
    t_from = _finite("t_from", t_from)
    if t_to is not None:
        t_to = _finite("t_to", t_to)
    last = float(ds["time"].values[-1])
    op, bad = (">=", "<=") if empty else (">", "<")
    if t_to is None and (t_from > last or (t_from == last and not empty)):
        raise ParameterError("t_from", f"{bad} the record's last time, {last:g} s", t_from)
    if t_to is not None and (t_to < t_from or (t_to == t_from and not empty)):
        raise ParameterError("t_to", f"{op} t_from = {t_from:g} s", t_to)
    return t_from, t_to


def contact_impulse(ds: xr.Dataset, t_from: float = 0.0, t_to: float | None = None) -> xr.Dataset:
    """Time-integrated contact forces over ``[t_from, t_to]``, N s.

    Uses the recorded interval means (exact integral of every step's force).
    Returns ``pair`` (per neighbouring pair, initial order) and ``wall``.
    """
    t_from, t_to = _interval(ds, t_from, t_to)
    dt = float(ds.attrs["sample_interval"])
    t = ds["time"]
    hi = t[-1] if t_to is None else t_to
    # the sample at time t holds the mean over (t - dt, t]
    sel = (t > t_from + 1e-12) & (t <= hi + 1e-12)
    out = xr.Dataset(
        {
            "pair": (ds["contact_force_pair"].where(sel, 0.0).sum("time") * dt),
            "wall": (ds["contact_force_wall"].where(sel, 0.0).sum("time") * dt),
        }
    )
    for v in out.data_vars.values():
        v.attrs = {"units": "N s"}
    return out


def mean_contact_force(ds: xr.Dataset, t_from: float = 0.0, t_to: float | None = None) -> xr.Dataset:
    """Time-averaged contact forces over ``(t_from, t_to]``, N."""
    t_from, t_to = _interval(ds, t_from, t_to, empty=False)  # a mean over no time is refused
    t = ds["time"].values
    hi = t[-1] if t_to is None else t_to
    imp = contact_impulse(ds, t_from, t_to)
    out = imp / (hi - t_from)
    for v in out.data_vars.values():
        v.attrs = {"units": "N"}
    return out


def middle_link_pose(ds) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre and heading of every swimmer's middle link ``N // 2`` (head = link 0;
    for even N the first link behind the middle joint) from a run's centre-line
    nodes: ``x, y`` (m) and ``heading`` (rad, head -> tail direction from +x,
    unwrapped over time), each (time, swimmer).

    The robots carry their tag on this link
    (:func:`undulate.track.calibration.robot_tag_link`) and the tracker measures
    its centre, so experiment and simulation are compared at the same body point.
    """
    _trajectory(ds, ("node_x", "node_y"), timed=False)  # geometry, sample by sample
    nx, ny = np.asarray(ds["node_x"].values, float), np.asarray(ds["node_y"].values, float)
    k = (nx.shape[-1] - 1) // 2
    x0, y0, x1, y1 = nx[..., k], ny[..., k], nx[..., k + 1], ny[..., k + 1]
    heading = np.unwrap(np.arctan2(y1 - y0, x1 - x0), axis=0)
    return 0.5 * (x0 + x1), 0.5 * (y0 + y1), heading
