"""Phase observables: gait phases, phase differences, order parameter, locking.

Pure functions of a recorded trajectory (an ``xarray.Dataset`` from
:func:`undulate.simulate`, or a tracked/robot experiment with the same
variables).  Conventions follow :mod:`undulate.control`:

* the **gait phase** ``psi_j`` (rad, unwrapped) of swimmer ``j`` grows by
  ``2 pi`` per undulation; its joints follow ``alpha_i = beta sin(2 pi xi i / N
  - psi_j)``; open loop ``psi_j = 2 pi f t - phi_j``;
* the paper's **phase offset** at time ``t`` is ``phi_j(t) = 2 pi f t - psi_j(t)``
  (constant in open loop), and neighbour phase differences are ``dphi =
  phi_upper - phi_lower`` wrapped into ``(-pi, pi]``, with neighbours in
  lateral order as in :mod:`undulate.observables`.

Two sources of the phase:

* :func:`gait_phase` -- what the controller commanded (recorded as
  ``gait_phase``; exact for simulations and for robots that log it);
* :func:`kinematic_phase` -- an **estimator from kinematics alone** (for
  videos, or to check what the body actually did): the Hilbert transform
  of each joint's angle over the whole record gives the joint's phase,
  ``alpha_i = a_i(t) sin(theta_i(t) + pi/2)``  ->  ``psi_i = theta_i + offset_i - pi/2``;
  the swimmer's phase is the circular mean over its joints.  The analytic
  signal is accurate away from the record's ends (it assumes the record
  holds whole periods; about one period at each end is distorted), so
  :func:`kinematic_phase` trims ``trim_periods`` at each end.
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from .errors import ParameterError
from .observables import _times, _trajectory, lateral_order, wrap_angle
from .params import _finite, _nonneg, _positive

__all__ = ["gait_phase", "kinematic_phase", "phase_offsets", "neighbour_phase_differences", "order_parameter",
           "time_to_lock", "gait_frequency"]


def _config(ds: xr.Dataset) -> dict:
    import json

    return json.loads(ds.attrs["config"])["scene"]


def _omega(ds: xr.Dataset) -> float:
    return 2 * math.pi / float(ds.attrs["period"])


def gait_phase(ds: xr.Dataset) -> xr.DataArray:
    """The commanded gait phase ``psi`` (time, swimmer), rad, unwrapped."""
    _trajectory(ds)
    if "gait_phase" in ds:
        return ds["gait_phase"]
    # older recordings without it: the open-loop gait's
    t = ds["time"]
    psi = _omega(ds) * t - ds["phase"]
    return psi.transpose("time", "swimmer").assign_attrs(units="rad", long_name="gait phase psi (open loop)")


def kinematic_phase(ds: xr.Dataset, trim_periods: float = 1.0) -> xr.DataArray:
    """Gait phase estimated from the joint angles alone (Hilbert transform), rad, unwrapped.

    Returns (time, swimmer) over the record minus ``trim_periods`` at each end.
    Each joint's angle is centred on its mean over the record, its analytic
    signal's phase ``theta_i`` gives ``psi_i = theta_i + offset_i - pi/2``
    (``alpha_i = beta sin(offset_i - psi)``), and the swimmer's phase is
    the circular mean of ``psi_i`` over the joints, unwrapped in time.
    """
    from scipy.signal import hilbert

    _trajectory(ds, ("joint_angle",), ("period",))
    trim_periods = _nonneg("trim_periods", trim_periods)
    cfg = _config(ds)
    n_links = int(cfg["geometry"]["n_links"])
    xi = float(cfg["gait"]["waves_per_body"])
    alpha = ds["joint_angle"].transpose("time", "swimmer", "joint").values
    theta = np.angle(hilbert(alpha - alpha.mean(axis=0), axis=0))
    # alpha = beta sin(offset - psi) = beta sin(psi - offset + pi), a rising argument; the analytic signal
    # of sin(x) is -i e^{ix}, so theta = x - pi/2 = psi - offset + pi/2
    offsets = 2 * np.pi * xi * np.arange(n_links - 1) / n_links
    psi_j = theta + offsets - np.pi / 2
    psi = np.unwrap(np.angle(np.exp(1j * psi_j).mean(axis=-1)), axis=0)
    # anchor the unwrapped branch on the commanded phase at the first kept sample
    t = ds["time"].values
    keep = (t >= t[0] + trim_periods * float(ds.attrs["period"])) & (t <= t[-1] - trim_periods * float(ds.attrs["period"]))
    if not keep.any():
        raise ValueError(f"record shorter than 2 x trim_periods = {2 * trim_periods:g} periods")
    ref = gait_phase(ds).values[keep][0]
    psi = psi[keep]
    psi = psi + 2 * np.pi * np.round((ref - psi[0]) / (2 * np.pi))
    return xr.DataArray(psi, dims=("time", "swimmer"), coords={"time": t[keep], "swimmer": ds["swimmer"].values},
                        attrs={"units": "rad", "long_name": "gait phase psi estimated from joint angles (Hilbert)"})


def phase_offsets(ds: xr.Dataset, psi: xr.DataArray | None = None) -> xr.DataArray:
    """The paper's phase offsets ``phi_j(t) = 2 pi f t - psi_j(t)`` (time, swimmer), rad, wrapped
    into (-pi, pi].  ``psi``: a phase (default: :func:`gait_phase`)."""
    psi = gait_phase(ds) if psi is None else psi
    phi = wrap_angle(_omega(ds) * psi["time"].values[:, None] - psi.values)
    return xr.DataArray(phi, dims=("time", "swimmer"), coords=psi.coords,
                        attrs={"units": "rad", "long_name": "phase offset phi = 2 pi f t - psi"})


def neighbour_phase_differences(ds: xr.Dataset, psi: xr.DataArray | None = None) -> xr.DataArray:
    """``dphi = phi_upper - phi_lower`` for laterally neighbouring swimmers (time, rank), rad,
    wrapped into (-pi, pi]; ranks as in :func:`undulate.observables.neighbour_offsets`."""
    psi = gait_phase(ds) if psi is None else psi
    order = lateral_order(ds).sel(time=psi["time"]).values  # (time, rank) -> swimmer index
    p = psi.values
    ranked = np.take_along_axis(p, order, axis=1)
    # dphi = phi_up - phi_lo = -(psi_up - psi_lo)
    d = wrap_angle(-(ranked[:, 1:] - ranked[:, :-1]))
    return xr.DataArray(d, dims=("time", "rank"), coords={"time": psi["time"].values},
                        attrs={"units": "rad", "long_name": "neighbour phase difference phi_upper - phi_lower"})


def _phases(da, name: str) -> np.ndarray:
    """``da``'s times (s) if it is a (time, swimmer or rank) DataArray of phases over increasing times."""
    if not isinstance(da, xr.DataArray) or da.ndim != 2 or da.dims[0] != "time":
        raise ParameterError(name, "an xarray.DataArray of phases (time, swimmer) or (time, rank), rad",
                             type(da).__name__ if not isinstance(da, xr.DataArray) else f"dims {da.dims}")
    return _times(da, name)


def order_parameter(psi: xr.DataArray) -> xr.DataArray:
    """Kuramoto order parameter ``R(t) = |<exp(i psi_j)>_j|`` (time), dimensionless in [0, 1]."""
    _phases(psi, "psi")
    r = np.abs(np.exp(1j * psi.values).mean(axis=1))
    return xr.DataArray(r, dims=("time",), coords={"time": psi["time"].values},
                        attrs={"units": "1", "long_name": "order parameter R"})


def gait_frequency(psi: xr.DataArray, t_from: float = 0.0, t_to: float | None = None) -> xr.DataArray:
    """Mean gait frequency of each swimmer over ``[t_from, t_to]``: the slope of a
    least-squares line through ``psi(t)`` / 2 pi, Hz (swimmer)."""
    t = _phases(psi, "psi")
    t_from = _finite("t_from", t_from)
    if t_to is not None and _finite("t_to", t_to) <= t_from:
        raise ParameterError("t_to", f"> t_from = {t_from:g} s", t_to)
    sel = (t >= t_from) & (t <= (t[-1] if t_to is None else t_to))
    if sel.sum() < 2:
        raise ValueError("fewer than two samples in the window")
    tt = t[sel] - t[sel].mean()
    slope = (tt[:, None] * (psi.values[sel] - psi.values[sel].mean(axis=0))).sum(axis=0) / (tt ** 2).sum()
    return xr.DataArray(slope / (2 * np.pi), dims=("swimmer",), attrs={"units": "Hz", "long_name": "gait frequency"})


def time_to_lock(dphi: xr.DataArray, tol_rad: float = 0.1, hold_s: float | None = None) -> xr.DataArray:
    """Time after which each neighbour phase difference stays within ``tol_rad`` of its
    final value (its circular mean over the last ``hold_s``, default the last 10 % of
    the record), s (rank); NaN if it never settles (still drifting at the end)."""
    t = _phases(dphi, "dphi")
    tol_rad = _positive("tol_rad", tol_rad, "rad")
    if hold_s is not None:
        hold_s = _nonneg("hold_s", hold_s, "s")
    hold = 0.1 * (t[-1] - t[0]) if hold_s is None else hold_s
    tail = t >= t[-1] - hold
    out = np.full(dphi.shape[1], np.nan)
    for r in range(dphi.shape[1]):
        d = dphi.values[:, r]
        final = np.angle(np.exp(1j * d[tail]).mean())
        off = np.abs(wrap_angle(d - final)) > tol_rad
        if off[tail].any():
            continue  # not settled at the end
        last_off = np.flatnonzero(off)
        out[r] = t[0] if last_off.size == 0 else t[min(last_off[-1] + 1, len(t) - 1)]
    return xr.DataArray(out, dims=("rank",), attrs={"units": "s", "long_name": "time to phase lock"})
