"""Analysis shared by the simulation studies: neighbours, steady state, compatibility fits.

* :func:`trajectory`, :func:`final_neighbours`, :func:`neighbour_series`
  and :func:`steady_offsets` turn one run of :func:`._runners.group_point`
  into nearest-neighbour offsets by **lateral order** and their steady values;
  :func:`collect_pairs` does it for an array of pair runs.
* :func:`compatibility_fit` (slope of ``dx/lambda`` against ``dphi/2pi``,
  with standard errors) and :func:`rms` (with a bootstrap interval) are the
  summary statistics, on :mod:`undulate.stats`.

Conventions are those of :mod:`undulate.params`: for lateral neighbours
(lower, upper in y) ``dx = x_upper - x_lower`` and ``dphi = phi_upper -
phi_lower``; compatibility is ``dx = lambda (dphi / 2 pi + n)``.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr

from .. import stats, theory
from ..observables import lateral_ranks, period_average, steady_state, wrap_angle
from ._criteria import GROUP_CHANNEL_M, GROUP_RMS_TOL, GROUP_SLOPE_TOL, STEADY_TOL, STEADY_WINDOW  # noqa: F401 - re-exported
from ._criteria import LINE_RMS_TOL, LINE_SLOPE_TOL
from ._runners import BODY_LENGTH_M, PERIOD_S

__all__ = [
    "FALLS_RULE",
    "falls_with_links",
    "falls_with_links_checks",
    "STEADY_TOL",
    "STEADY_WINDOW",
    "STEADY_RULE",
    "paper_phases",
    "phase_grid",
    "stepped",
    "trajectory",
    "final_neighbours",
    "neighbour_series",
    "steady_offsets",
    "Steady",
    "pair_record",
    "collect_pairs",
    "SLOPE_METHOD",
    "unwrap_to_line",
    "compatibility_fit",
    "band_excess",
    "rms",
    "group_records",
    "sweep_runs",
    "GROUP_CHANNEL_M",
    "GROUP_DRAWS",
    "group_phases",
    "group_cap_phases",
    "refined",
    "GROUP_CAP_REFINE",
    "GROUP_CAP_DRAWS",
    "IMPULSE_CAP_PHASES",
    "impulse_design",
    "GROUP_SLOPE_TOL",
    "GROUP_RMS_TOL",
    "group_follows_line",
    "group_follows_line_checks",
    "line_checks",
]

GROUP_DRAWS = {True: 8, False: 40}
"""Random phase draws of the groups of four: quick mode (True) and full mode (False)."""
GROUP_FULL_PHASES = 33
"""dphi of the groups of three (and their reference pairs) in full mode: step pi/16 over [-pi, pi]
(the groups study's third look; the sensitivity study reruns this design)."""
GROUP_CAP_REFINE = 12
"""Full mode's cap for the groups of three: every step of the :data:`GROUP_FULL_PHASES` grid cut into
this many (385 dphi, step pi/192; :func:`group_cap_phases`)."""
GROUP_CAP_DRAWS = 120
"""Random phase draws of the groups of four at full mode's cap (the study's fourth look)."""
IMPULSE_PHASES = {True: 9, False: 37}
"""dphi of the two-period contact-impulse runs over [-pi, pi] (both ends): quick mode (True), full (False)."""
IMPULSE_CAP_PHASES = 73
"""dphi of the contact-impulse runs at full mode's cap (the potential study's fourth look, step pi/36;
every second one is :data:`IMPULSE_PHASES`'s full grid)."""
IMPULSE_COMMON_PHASES = {True: 4, False: 8}
"""Common phases phi0 (swimmer 0's phase, equally spaced over [0, 2 pi)) the impulse is averaged over."""

STEADY_RULE = (
    f"observables.steady_state on period averages (period {PERIOD_S:g} s) of dx/lambda "
    f"(dx/L for the standing wave xi = 0, lambda = inf): steady when the last {STEADY_WINDOW} "
    f"period averages lie within {STEADY_TOL:g} of their mean; the steady value is that mean"
)


def paper_phases() -> np.ndarray:
    """The paper's nine phase differences ``{-1, -3/4, ..., 1} pi``, rad."""
    return np.arange(-4, 5) * (np.pi / 4)


def phase_grid(n: int) -> np.ndarray:
    """``n`` equally spaced phase differences over ``[-pi, pi]`` (both ends), rad.

    With ``n = 8 k + 1`` the grid contains the paper's nine values.
    """
    return np.linspace(-np.pi, np.pi, int(n))


def group_phases(quick: bool) -> np.ndarray:
    """dphi (rad) of the groups of three and their reference pairs: the paper's nine in quick mode,
    :data:`GROUP_FULL_PHASES` in full mode.  One design for the groups study and for every study that
    reruns its groups (``sensitivity``), so that those differ from it only in what they vary."""
    return paper_phases() if quick else phase_grid(GROUP_FULL_PHASES)


def refined(grid: Sequence[float], k: int) -> np.ndarray:
    """``grid`` with every step cut into ``k`` equal ones: ``refined(g, k)[::k]`` is ``g``, bitwise (a
    finer ``linspace`` is not: its every ``k``-th value can differ from the coarse one in the last
    bit, and the coarse grid's runs would not be found again in the content-keyed stores)."""
    g = np.asarray(grid, float)
    k = int(k)
    if k < 1 or g.ndim != 1 or g.size < 2:
        raise ValueError(f"refined needs a 1-D grid of >= 2 values and k >= 1, not {g.size} values, k = {k}")
    frac = np.arange(k) / k
    inner = (g[:-1, None] + frac[None, :] * np.diff(g)[:, None]).ravel()
    out = np.append(inner, g[-1])
    out[::k] = g
    return out


def group_cap_phases() -> np.ndarray:
    """dphi (rad) of the groups of three at full mode's cap: :func:`group_phases` (full) refined by
    :data:`GROUP_CAP_REFINE` (385 values over [-pi, pi])."""
    return refined(group_phases(False), GROUP_CAP_REFINE)


def impulse_design(quick: bool) -> tuple[np.ndarray, np.ndarray]:
    """``(dphi, phi0)`` (rad) of the two-period contact-impulse runs (``pair_point`` from dx0 = 0): the
    potential study's, and that of every study that reruns them (``sensitivity``), so that those differ
    from it only in what they vary.  Quick: 9 dphi x 4 phi0; full: 37 x 8."""
    phi0 = np.linspace(0.0, 2 * np.pi, IMPULSE_COMMON_PHASES[quick], endpoint=False)
    return phase_grid(IMPULSE_PHASES[quick]), phi0


def positions(values, subset) -> list[int]:
    """Index in ``values`` of each of ``subset`` (a staged look's thinned values: equal to ``values``'
    bitwise, compared within 1e-12)."""
    v = np.asarray(values, float)
    return [int(np.flatnonzero(np.isclose(v, d, rtol=0, atol=1e-12))[0]) for d in subset]


def point_index(dphis, row_dphis) -> np.ndarray:
    """Index of each (row, dphi) into an explicit-point sweep whose points run row by row, each row over
    its own ``row_dphis[i]`` (a staged look's subset of ``dphis``: a frozen claim's runs); -1 where a
    row has no run.  Shape ``(len(row_dphis), len(dphis))``."""
    index = np.full((len(row_dphis), len(dphis)), -1)
    k = 0
    for i, d in enumerate(row_dphis):
        cols = positions(dphis, d)
        index[i, cols] = np.arange(k, k + len(cols))
        k += len(cols)
    return index


def runs_made(d) -> np.ndarray:
    """Where a study dataset ``d`` holds a run (its ``run_made`` variable; every point of a dataset written
    before ``run_made`` existed)."""
    return d["run_made"].values if "run_made" in d else np.ones(d["run_failed"].shape, bool)


def abs_dphi_keys(dphi) -> np.ndarray:
    """|dphi| rounded to 1e-9 rad: equal for +dphi and -dphi of one grid (one design point, :func:`by_abs_dphi`)."""
    return np.round(np.abs(np.asarray(dphi, float).ravel()), 9)


def by_abs_dphi(dphi, values) -> tuple[np.ndarray, np.ndarray]:
    """The runs at each |dphi| together, for a fit on |dphi|: ``(|dphi| values, increasing; their runs,
    one row each, NaN-padded)``.  ``values``: one row per ``dphi`` (e.g. the common phases of the impulse
    runs), or one value each.  dphi and -dphi are one design point, not two: the pair at -dphi is the pair
    at +dphi mirrored (swimmers swapped, reflected across the channel: phi0 -> phi0 + dphi + pi), so on the
    common-phase grid some rows repeat others run for run, and dphi = +-pi is one state.  A bootstrap over
    the rows would count each |dphi| twice; over these rows it counts it once."""
    keys = abs_dphi_keys(dphi)
    v = np.asarray(values, float).reshape(keys.size, -1)
    u = np.unique(keys)
    rows = [v[keys == k].ravel() for k in u]
    out = np.full((u.size, max((r.size for r in rows), default=0)), np.nan)
    for i, r in enumerate(rows):
        out[i, :r.size] = r
    return u, out


def row_means(values) -> np.ndarray:
    """Each row's mean over its values that are not NaN (:func:`by_abs_dphi`'s NaN-padded rows), as
    ``np.nanmean(values, axis=1)`` gives it, but NaN without NumPy's "Mean of empty slice" warning for
    a row with none (its runs failed or were not run)."""
    v = np.asarray(values, float)
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "Mean of empty slice", RuntimeWarning)
        return np.nanmean(v.reshape(len(v), -1 if v.size else 0), axis=1)


# ------------------------------------------------------------------ analysis
def stepped(run: xr.Dataset) -> xr.Dataset:
    """A run cut to the samples it stepped: a run its stopping rule ended early
    (``stopped_at_s``) is NaN after that on the sweep's common time axis."""
    if "stopped_at_s" not in run or not np.isfinite(float(run["stopped_at_s"])):
        return run
    return run.isel(time=np.flatnonzero(run["time"].values <= float(run["stopped_at_s"]) + 1e-9))


def trajectory(run: xr.Dataset, wavelength_m: float, period_s: float = PERIOD_S) -> xr.Dataset:
    """One run (a slice of the sweep dataset) as a trajectory the observables accept.

    Needs ``x``, ``y`` (time, swimmer) and ``phase`` (swimmer); sets the
    ``phase`` coordinate and the ``wavelength`` and ``period`` attributes.
    A stopped run is cut to the samples it stepped (:func:`stepped`).
    """
    run = stepped(run)
    ds = xr.Dataset({"x": run["x"], "y": run["y"]},
                    coords={"time": run["time"], "phase": ("swimmer", np.asarray(run["phase"].values, float))})
    ds.attrs.update(wavelength=float(wavelength_m), period=float(period_s))
    return ds


def final_neighbours(ds: xr.Dataset, period_s: float | None = None,
                     window: int = STEADY_WINDOW) -> tuple[list[tuple[int, int]], bool]:
    """Neighbouring swimmer ids ``(lower, upper)`` by lateral order at the end of a run.

    ``ds``: a trajectory with ``y`` (time, swimmer).  The order is that of
    the swimmers' **mean** ``y`` over the last ``window`` whole periods (the
    steady-state window), not of one sample: bodies that interdigitate
    (e.g. dphi = pi) cross each other's centre-of-mass ``y`` within every
    cycle, so an instantaneous order flips back and forth.  Returns the
    pairs, bottom to top, and whether every single period of the window has
    the same order of its mean ``y`` (False: the swimmers were still
    changing lateral places).  Ranks by :func:`undulate.observables.lateral_ranks`,
    the rule :func:`undulate.observables.lateral_order` follows sample by sample.
    """
    if period_s is None:
        period_s = float(ds.attrs.get("period", PERIOD_S))
    pa = period_average(ds["y"], period_s).transpose("time", "swimmer").values[-window:]
    last = lateral_ranks(pa.mean(axis=0))
    pairs = [(int(a), int(b)) for a, b in zip(last[:-1], last[1:])]
    stable = bool((lateral_ranks(pa) == last).all())
    return pairs, bool(stable)


def neighbour_series(ds: xr.Dataset, lower: int, upper: int) -> tuple[xr.DataArray, xr.DataArray, float]:
    """``dx(t) = x_upper - x_lower``, ``dy(t)`` (m) and ``dphi = wrap(phi_upper - phi_lower)`` (rad).

    The pair is fixed by id (e.g. from :func:`final_neighbours`), so the
    series stays continuous even if the swimmers swapped lateral places on
    the way.  ``dphi`` is wrapped into (-pi, pi].
    """
    dx = (ds["x"].isel(swimmer=upper) - ds["x"].isel(swimmer=lower)).assign_attrs(units="m")
    dy = (ds["y"].isel(swimmer=upper) - ds["y"].isel(swimmer=lower)).assign_attrs(units="m")
    phase = np.asarray(ds["phase"].values, float)
    dphi = float(wrap_angle(phase[upper] - phase[lower]))
    return dx.drop_vars([c for c in dx.coords if c != "time"]), \
        dy.drop_vars([c for c in dy.coords if c != "time"]), dphi


@dataclass(frozen=True)
class Steady:
    """Steady value of one neighbour offset (see :data:`STEADY_RULE`)."""

    dx_m: float
    """Steady dx, m (the mean of the last window's period averages)."""
    steady: bool
    settle_time_s: float
    spread: float
    """Max deviation of the last window's period averages from their mean, in dx/scale."""
    dy_m: float
    """Mean dy over the last window, m."""


def steady_offsets(dx: xr.DataArray, dy: xr.DataArray, wavelength_m: float,
                   period_s: float = PERIOD_S) -> Steady:
    """Apply the steady-state rule to ``dx / lambda`` (``dx / L`` when lambda = inf)."""
    scale = wavelength_m if math.isfinite(wavelength_m) else BODY_LENGTH_M
    ss = steady_state(dx / scale, period_s=period_s, tol=STEADY_TOL, window=STEADY_WINDOW)
    t = dy["time"].values
    n_full = int(np.floor((t[-1] - t[0]) / period_s + 1e-9))
    lo, hi = t[0] + (n_full - STEADY_WINDOW) * period_s, t[0] + n_full * period_s
    dy_last = float(dy.where((dy["time"] > lo + 1e-9) & (dy["time"] <= hi + 1e-9)).mean())
    return Steady(dx_m=float(ss["value"]) * scale, steady=bool(ss["steady"]),
                  settle_time_s=float(ss["settle_time"]), spread=float(ss["spread"]), dy_m=dy_last)


def _last_window_mean(da: xr.DataArray, period_s: float = PERIOD_S) -> float:
    """Mean of a (time, ...) series over the steady-state window (last whole periods)."""
    t = da["time"].values
    n_full = int(np.floor((t[-1] - t[0]) / period_s + 1e-9))
    lo, hi = t[0] + (n_full - STEADY_WINDOW) * period_s, t[0] + n_full * period_s
    sel = (t > lo + 1e-9) & (t <= hi + 1e-9)
    return float(np.nanmean(da.values[sel]))


PAIR_FIELDS = ("dx_steady", "dy_steady", "steady", "settle_time", "steady_spread", "swapped",
               "order_stable", "residual", "band_excess", "contact_force_mean", "joint_error_mean",
               "penetration_max")


def pair_record(run: xr.Dataset, dphi_rad: float, wavelength_m: float, amplitude_m: float
                ) -> tuple[dict[str, float], np.ndarray]:
    """Steady state of one pair run (2 swimmers; swimmer 1 has phase ``dphi_rad``, swimmer 0 has 0).

    Neighbours are identified by lateral order at the end of the run
    (:func:`final_neighbours`), giving ``(dx, dphi)`` = ``(x_upper - x_lower,
    phi_upper - phi_lower)``.  If the swimmers swapped lateral places, that
    point is reflected through the origin to ``(-dx, -dphi)``, which
    describes the same configuration (compatibility is odd in both) and
    puts it at the nominal ``dphi_rad``: in every case the reported offset
    is ``x_1 - x_0``.  Returns the scalars of :data:`PAIR_FIELDS` (m, s, N,
    rad, flags as floats) and the series ``x_1(t) - x_0(t)`` (m).
    """
    n_time = run.sizes["time"]
    run = stepped(run)
    traj = trajectory(run, wavelength_m)
    pairs, stable = final_neighbours(traj)
    (lo, up), = pairs
    swapped = lo != 0
    dx, dy, _ = neighbour_series(traj, lo, up)
    sign = -1.0 if swapped else 1.0
    dx = dx * sign
    st = steady_offsets(dx, dy, wavelength_m)
    lam = wavelength_m
    res = float(theory.compatibility_residual(st.dx_m, dphi_rad, lam)) if math.isfinite(lam) else math.nan
    exc = float(band_excess(st.dx_m, dphi_rad, st.dy_m, amplitude_m, lam)) if math.isfinite(lam) else math.nan
    rec = {
        "dx_steady": st.dx_m, "dy_steady": st.dy_m, "steady": float(st.steady),
        "settle_time": st.settle_time_s, "steady_spread": st.spread, "swapped": float(swapped),
        "order_stable": float(stable), "residual": res, "band_excess": exc,
        "contact_force_mean": _last_window_mean(run["contact_force_pair"].isel(pair=0)),
        "joint_error_mean": _last_window_mean(run["joint_error"].mean("swimmer")),
        "penetration_max": float(run["penetration_max"]),
    }
    series = np.full(n_time, np.nan)  # on the sweep's common axis (NaN after a stop)
    series[:dx.sizes["time"]] = dx.values
    return rec, series


PAIR_ATTRS = {
    "dx_steady": ("m", "steady longitudinal offset x_1 - x_0 (= x_upper - x_lower up to reflection)"),
    "dy_steady": ("m", "lateral offset y_upper - y_lower, mean over the steady-state window"),
    "settle_time": ("s", "start of the steady state (NaN if not steady)"),
    "steady_spread": ("1", "max deviation of the last window's period averages from their mean, "
                           "in units of lambda (L for xi = 0)"),
    "residual": ("m", "signed distance of dx_steady from the nearest compatibility branch "
                      "lambda (dphi/2pi + n) (theory.compatibility_residual)"),
    "band_excess": ("m", "distance of dx_steady outside the full compatibility band at the measured "
                         "dy_steady and free-swimmer amplitude A (0 = inside)"),
    "contact_force_mean": ("N", "mean swimmer-swimmer contact force over the steady-state window"),
    "joint_error_mean": ("rad", "mean joint error over the steady-state window"),
    "penetration_max": ("m", "deepest interpenetration of the run"),
}
PAIR_FLAGS = {
    "steady": "steady by the rule in attrs['steady_rule']",
    "swapped": "the swimmers ended in swapped lateral order (point reflected to the nominal dphi)",
    "order_stable": "lateral order unchanged over the steady-state window",
}


def collect_pairs(runs, failed, dphi_rad, wavelength_m, amplitude_m, dims):
    """Analyse an array of pair runs into study variables.

    ``runs(idx)`` returns the run Dataset at index tuple ``idx`` of shape
    ``failed.shape``; ``dphi_rad``, ``wavelength_m``, ``amplitude_m`` are
    arrays of that shape (broadcast); ``dims`` names its axes.  Returns
    ``(variables, dx_t)``: a dict of ``xarray.Variable`` (:data:`PAIR_FIELDS`
    plus ``dx_steady_over_lambda``, ``residual_over_lambda``,
    ``run_failed``) and the array of ``x_1 - x_0`` series (shape + (time,)).
    Failed runs are NaN (flags False).
    """
    failed = np.asarray(failed, bool)
    shape = failed.shape
    dphi = np.broadcast_to(np.asarray(dphi_rad, float), shape)
    lam = np.broadcast_to(np.asarray(wavelength_m, float), shape)
    amp = np.broadcast_to(np.asarray(amplitude_m, float), shape)
    out = {k: np.full(shape, np.nan) for k in PAIR_FIELDS}
    dx_t = None
    for idx in np.ndindex(*shape):
        if failed[idx]:
            continue
        rec, series = pair_record(runs(idx), float(dphi[idx]), float(lam[idx]), float(amp[idx]))
        if dx_t is None:
            dx_t = np.full(shape + series.shape, np.nan)
        dx_t[idx] = series
        for k, v in rec.items():
            out[k][idx] = v
    with np.errstate(invalid="ignore", divide="ignore"):
        finite = np.isfinite(lam)
        over = {"dx_steady_over_lambda": np.where(finite, out["dx_steady"] / lam, np.nan),
                "residual_over_lambda": np.where(finite, out["residual"] / lam, np.nan)}
    variables = {}
    for k, (units, long_name) in PAIR_ATTRS.items():
        variables[k] = xr.Variable(dims, out[k], {"units": units, "long_name": long_name})
    for k, long_name in PAIR_FLAGS.items():
        variables[k] = xr.Variable(dims, out[k] == 1.0, {"long_name": long_name})
    variables["dx_steady_over_lambda"] = xr.Variable(dims, over["dx_steady_over_lambda"], {
        "units": "1", "long_name": "dx_steady / lambda (NaN for xi = 0)"})
    variables["residual_over_lambda"] = xr.Variable(dims, over["residual_over_lambda"], {
        "units": "1", "long_name": "residual / lambda: distance from the nearest compatibility branch"})
    variables["run_failed"] = xr.Variable(dims, failed, {"long_name": "the simulation failed (no result)"})
    return variables, dx_t


# ------------------------------------------------------------------ statistics
def unwrap_to_line(dx_over_lambda, dphi_rad) -> np.ndarray:
    """Move each ``dx/lambda`` by a whole wavelength onto the branch nearest the line through 0.

    ``dx/lambda + n`` with ``n`` the integer that brings the point closest to
    ``dphi/2pi`` (the n = 0 compatibility branch): this is
    ``dphi/2pi + compatibility_residual/lambda``.  Branches repeat every
    wavelength, so this changes no physical configuration; it only undoes
    the wrap at ``dphi = +-pi`` (the same physical state) before a line fit.
    """
    r = theory.compatibility_residual(np.asarray(dx_over_lambda, float), np.asarray(dphi_rad, float), 1.0)
    return np.asarray(dphi_rad, float) / (2 * np.pi) + r


SLOPE_METHOD = (
    "least squares of dx/lambda against dphi/2pi over every run with a result, after moving each "
    "dx/lambda by whole wavelengths onto the branch nearest the n = 0 line dx/lambda = dphi/2pi (i.e. "
    "dphi/2pi + nearest-branch residual; this undoes the wrap at dphi = +-pi, which is one physical "
    "state). On a mirror-symmetric dphi grid (every |dphi| once at +dphi and once at -dphi: the pairs, "
    "links, swimming and sensitivity studies' grids) the runs at +dphi and -dphi are one design point "
    "seen mirrored: the slope's Student-t "
    "interval counts the pairs (the half-differences regressed through the origin, G - 1 degrees of "
    "freedom; stats.mirrored_line_fit) and R^2's BCa bootstrap resamples each pair together; a run "
    "whose mirror has no result is left out. The neighbour pairs of groups (several rows a run): the "
    "least-squares slope with the cluster jackknife (CR3) standard error and a t interval on G - 1 "
    "degrees of freedom for G clusters, a run's neighbour pairs and the runs at +dphi and -dphi one "
    "cluster (stats.clustered_line_fit), R^2 by a cluster bootstrap. Over another grid: scipy.stats.linregress, t "
    "interval on n - 2 degrees of freedom, R^2 by a row bootstrap. "
    "'slope_open_interval' is the same fit without unwrapping over |dphi| < pi only"
)


def compatibility_fit(dx_over_lambda, dphi_rad, unwrap: bool = True, *,
                      mirrored: bool | None = None, runs=None) -> stats.LineFit:
    """Fit ``dx/lambda`` against ``dphi/2pi`` (see :data:`SLOPE_METHOD`); rows without a result (NaN) are
    skipped.  ``runs``: the run of each row, where one run gives several rows (the neighbour pairs of a
    group): :func:`~undulate.stats.clustered_line_fit`, a run's rows and the rows at +dphi and -dphi
    (:func:`abs_dphi_keys`) one cluster; ``mirrored`` is then not used.  Otherwise ``mirrored``: True,
    the dphi are a mirror-symmetric grid, one run each (:func:`~undulate.stats.mirrored_line_fit`: the
    slope's interval counts the mirror pairs; ``ValueError`` if they are not); False, rows as independent
    points (:func:`~undulate.stats.line_fit`); None (default), True where the dphi given (with or without
    a result) are such a grid (:func:`~undulate.stats.is_mirror_design`)."""
    y = np.asarray(dx_over_lambda, float).ravel()
    x = np.asarray(dphi_rad, float).ravel()
    design = np.isfinite(x)
    x, y = x[design], y[design]
    if unwrap:
        y = unwrap_to_line(y, x)  # NaN stays NaN
    if runs is not None:
        run = np.asarray(runs).ravel()
        if run.size != design.size:
            raise ValueError(f"runs must give one run per row ({design.size}), not {run.size}")
        return stats.clustered_line_fit(x / (2 * np.pi), y, run_clusters(run[design], x))
    if mirrored is None:
        mirrored = stats.is_mirror_design(x)
    if mirrored:
        return stats.mirrored_line_fit(x / (2 * np.pi), y)
    ok = np.isfinite(y)
    return stats.line_fit(x[ok] / (2 * np.pi), y[ok])


def band_excess(dx_m, dphi_rad, dy_m, amplitude_m, wavelength_m):
    """How far (m) a configuration lies outside the full compatibility band.

    ``lambda / 2 pi * max(0, |psi| - 2 arcsin(min(|dy| / 2A, 1)))`` with
    ``psi`` the phase mismatch (paper Eq. (fullcompatibility)): 0 inside the
    band (the bodies need not touch at that lateral offset), else the
    longitudinal distance to the band's edge.  NaN for lambda = inf.
    """
    lam = float(wavelength_m)
    if not math.isfinite(lam):
        return np.full(np.shape(dx_m), np.nan)
    psi = theory.phase_mismatch(dphi_rad, dx_m, lam)
    half = theory.max_phase_mismatch(dy_m, amplitude_m)
    return lam / (2 * np.pi) * np.maximum(0.0, np.abs(psi) - half)


def rms(values: Sequence[float] | np.ndarray, dphi=None, runs=None) -> stats.Estimate:
    """Root mean square over the finite values, with a seeded BCa bootstrap 95 % interval
    (:func:`undulate.stats.rms`; NaN when there are none).  ``dphi``: each value's phase difference
    (radians); the values at +dphi and -dphi are then resampled together (:func:`abs_dphi_keys`): the
    pair at -dphi is the pair at +dphi mirrored (:func:`by_abs_dphi`), so their residuals are one
    design point seen twice, and dphi = +-pi one state.  ``runs``: each value's run, where a run gives
    several (a group's neighbour pairs): a run's values are resampled together too
    (:func:`~undulate.stats.joined_clusters`)."""
    if runs is not None:
        keys = run_clusters(runs, dphi)
    else:
        keys = None if dphi is None else abs_dphi_keys(dphi)
    return stats.rms(values, clusters=keys)


def run_clusters(runs, dphi=None) -> np.ndarray:
    """One cluster label per row: the rows of a run (a group's neighbour pairs) together, and with
    ``dphi`` (radians) the runs at +dphi and -dphi too (:func:`abs_dphi_keys`: one design point
    mirrored); :func:`~undulate.stats.joined_clusters`."""
    run = np.asarray(runs).ravel()
    return stats.joined_clusters(run) if dphi is None else stats.joined_clusters(run, abs_dphi_keys(dphi))


FALLS_RULE = ("the RMS residual rises at no step in N beyond its uncertainty (no 95 % interval lies wholly above "
              "the previous N's) and its 95 % interval at the largest N lies wholly below that at N = 3 "
              "(fails on a rise beyond the intervals or a largest-N interval wholly above N = 3's; undecided "
              "when the largest N's interval overlaps N = 3's)")
"""The link-number criterion ("the error falls as links are added"), judged on the intervals."""


def falls_with_links_checks(rms_by_n: Sequence[stats.Estimate], n_links: Sequence[int] | None = None
                            ) -> list[stats.Check]:
    """:data:`FALLS_RULE` on RMS residuals in increasing N, one :class:`~undulate.stats.Check` per criterion.

    One check per step (never undecided: a step is a rise only when its interval lies wholly above the
    previous one's, so a point value 0.0003 lambda higher inside overlapping intervals -- the 0.5 mm
    floor that recoil-free smooth bodies reach at N = 7 and 9 -- is no evidence that the error grows),
    and one for the overall fall (:meth:`~undulate.stats.Check.apart`: the largest N's interval wholly
    below the first's holds, wholly above fails, overlapping is undecided).  ``n_links`` labels the
    steps (default 1, 2, ...).  A step or the overall fall without an interval is undecided."""
    seq = list(rms_by_n)
    ns = list(n_links) if n_links is not None else list(range(1, len(seq) + 1))
    checks = []
    for (na, a), (nb, b) in zip(zip(ns, seq), zip(ns[1:], seq[1:])):
        what = f"RMS at N = {na} -> {nb}"
        if not (a.has_interval and b.has_interval):
            checks.append(stats.Check(None, f"{what}: no interval"))
        elif b.low > a.high:
            checks.append(stats.Check.exact(False, f"{what}: [{b.low:.3g}, {b.high:.3g}] wholly above "
                                                   f"[{a.low:.3g}, {a.high:.3g}] (a rise)"))
        else:
            checks.append(stats.Check.exact(True, f"{what}: no rise beyond the intervals"))
    if len(seq) >= 2:
        checks.append(stats.Check.apart(seq[0], seq[-1], f"RMS at N = {ns[0]} above N = {ns[-1]}"))
    return checks


def falls_with_links(rms_by_n: Sequence[stats.Estimate]) -> bool | None:
    """:data:`FALLS_RULE` on RMS residuals in increasing N: True holds, False fails, None undecided
    (the first and last intervals overlap) or no verdict (fewer than two, or one without an interval).
    :func:`falls_with_links_checks` decided by :func:`undulate.stats.decide`."""
    seq = list(rms_by_n)
    if len(seq) < 2 or not all(r.has_interval for r in seq):
        return None
    return stats.decide(falls_with_links_checks(seq))


def group_records(traj: xr.Dataset, amplitude_m: float) -> list[dict]:
    """Nearest-neighbour steady offsets of one group run, bottom to top.

    ``traj``: a trajectory (:func:`trajectory`: ``x``, ``y``,
    ``phase``, attrs ``wavelength`` and ``period``).  Neighbours are taken in
    the lateral order at the end of the run (:func:`final_neighbours`)
    and followed by id over the whole run, so a swap on the way does not
    break the series.  One dict per neighbouring pair with the keys of
    ``groups.NEIGHBOUR_FIELDS`` (but ``group_size`` and ``run_index``) and
    ``groups.NEIGHBOUR_FLAGS``.
    """
    lam = float(traj.attrs["wavelength"])
    pairs, stable = final_neighbours(traj)
    ids = [p[0] for p in pairs] + [pairs[-1][1]]
    changed = ids != sorted(ids)
    out = []
    for rank, (lo, up) in enumerate(pairs):
        dx, dy, dphi = neighbour_series(traj, lo, up)
        st = steady_offsets(dx, dy, lam)
        res = float(theory.compatibility_residual(st.dx_m, dphi, lam))
        out.append({
            "rank": rank, "lower": lo, "upper": up, "dphi": dphi,
            "dx_steady": st.dx_m, "dx_steady_over_lambda": st.dx_m / lam, "dy_steady": st.dy_m,
            "residual": res, "residual_over_lambda": res / lam,
            "band_excess": float(band_excess(st.dx_m, dphi, st.dy_m, amplitude_m, lam)),
            "settle_time": st.settle_time_s, "steady": st.steady, "order_stable": stable,
            "order_changed": changed,
        })
    return out


def sweep_runs(sweep: xr.Dataset):
    """(run Dataset or None if failed) for every run of a sweep, flattened in grid order."""
    flat = sweep.stack(run=[d for d in sweep["run_failed"].dims]).transpose("run", ...)
    for k in range(flat.sizes["run"]):
        r = flat.isel(run=k)
        yield None if bool(r["run_failed"]) else r


def line_checks(slope: stats.Estimate, rms: stats.Estimate, who: str = "") -> list[stats.Check]:
    """"Follows the compatibility line" (the pairs criterion) as checks: the slope's interval within
    1 +- :data:`LINE_SLOPE_TOL`, the RMS residual's below :data:`LINE_RMS_TOL` lambda (``who``: whose,
    e.g. "swimming pairs' ", in the checks' texts)."""
    return [slope.within(1 - LINE_SLOPE_TOL, 1 + LINE_SLOPE_TOL, f"{who}slope"),
            rms.below(LINE_RMS_TOL, f"{who}RMS residual (lambda)")]


def group_follows_line_checks(slope: stats.Estimate, rms: stats.Estimate,
                              pair_rms: stats.Estimate) -> list[stats.Check]:
    """The groups claim's criterion on 95 % intervals, as three :class:`~undulate.stats.Check` objects:
    the slope within 1 +- :data:`GROUP_SLOPE_TOL`, the RMS residual below :data:`GROUP_RMS_TOL` and
    wholly above the reference pairs' ``pair_rms`` (more scatter; overlapping intervals leave it
    undecided)."""
    return [slope.within(1 - GROUP_SLOPE_TOL, 1 + GROUP_SLOPE_TOL, "slope"),
            rms.below(GROUP_RMS_TOL, "RMS residual (lambda)"),
            stats.Check.apart(rms, pair_rms, "RMS residual vs the pairs' (lambda)")]


def group_follows_line(slope: stats.Estimate, rms: stats.Estimate, pair_rms: stats.Estimate) -> bool | None:
    """:func:`group_follows_line_checks` decided (:func:`undulate.stats.decide`): True holds, False
    fails, None undecided (an interval straddles its bound, or the RMS intervals overlap) or an
    interval is missing."""
    if not (slope.has_interval and rms.has_interval and pair_rms.has_interval):
        return None
    return stats.decide(group_follows_line_checks(slope, rms, pair_rms))
