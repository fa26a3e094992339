"""Study ``groups`` (paper Fig. 6): nearest neighbours in groups of three and four swimmers.

Three 3-link swimmers in a channel d = 0.19 m with phases ``(0, dphi,
2 dphi)`` in their initial lateral stack (neighbours differ by dphi) at the
paper's nine dphi (full mode: 33 values over [-pi, pi]); four swimmers in
d = 0.22 m with every phase drawn uniformly from [0, 2 pi) (each draw seeded
from ``config.seed`` through the sweep's per-run seeds; quick: 8 draws,
full: 40).  xi = 1, 30 s, start straight, laterally in contact, dx0 = 0.

Neighbours are identified by **lateral order** at the end of the run (the
order of the swimmers' mean y over the steady-state window,
``_common.final_neighbours``): for each neighbouring pair ``dx = x_upper -
x_lower`` and ``dphi = wrap(phi_upper - phi_lower)`` into (-pi, pi].  The
steady dx is compared with the compatibility branches ``lambda (dphi/2pi +
n)``.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from .. import theory
from ..sweep import Grid
from . import _common as C
from ._registry import StudyConfig, StudyResult, register

XI = 1.0
CHANNEL_WIDTH_M = {3: 0.19, 4: 0.22}
N_DRAWS = {True: 8, False: 40}
FULL_PHASES = 33

NEIGHBOUR_FIELDS = {
    "group_size": ("1", "swimmers in the group"),
    "run_index": ("1", "run of the pair (coordinate 'run' of the trajectories)"),
    "rank": ("1", "lateral rank of the lower swimmer of the pair (0 = lowest)"),
    "lower": ("1", "id of the lower swimmer (initial stack order)"),
    "upper": ("1", "id of the upper swimmer"),
    "dphi": ("rad", "phase difference phi_upper - phi_lower, wrapped into (-pi, pi]"),
    "dx_steady": ("m", "steady longitudinal offset x_upper - x_lower"),
    "dx_steady_over_lambda": ("1", "dx_steady / lambda"),
    "dy_steady": ("m", "lateral offset y_upper - y_lower over the steady-state window"),
    "residual": ("m", "signed distance of dx_steady from the nearest compatibility branch"),
    "residual_over_lambda": ("1", "residual / lambda"),
    "band_excess": ("m", "distance outside the full compatibility band at dy_steady and the free "
                         "swimmer's A (0 = inside)"),
    "settle_time": ("s", "start of the steady state (NaN if not steady)"),
}
NEIGHBOUR_FLAGS = {
    "steady": "steady by the rule in attrs['steady_rule']",
    "order_stable": "the group's lateral order was the same in every period of the steady window",
    "order_changed": "the group's final lateral order differs from the initial stack",
}


def phases(quick: bool) -> np.ndarray:
    return C.paper_phases() if quick else C.phase_grid(FULL_PHASES)


def group_records(traj: xr.Dataset, amplitude_m: float) -> list[dict]:
    """Nearest-neighbour steady offsets of one group run, bottom to top.

    ``traj``: a trajectory (:func:`_common.trajectory`: ``x``, ``y``,
    ``phase``, attrs ``wavelength`` and ``period``).  Neighbours are taken in
    the lateral order at the end of the run (:func:`_common.final_neighbours`)
    and followed by id over the whole run, so a swap on the way does not
    break the series.  One dict per neighbouring pair with the keys of
    :data:`NEIGHBOUR_FIELDS` (but ``group_size`` and ``run_index``) and
    :data:`NEIGHBOUR_FLAGS`.
    """
    lam = float(traj.attrs["wavelength"])
    pairs, stable = C.final_neighbours(traj)
    ids = [p[0] for p in pairs] + [pairs[-1][1]]
    changed = ids != sorted(ids)
    out = []
    for rank, (lo, up) in enumerate(pairs):
        dx, dy, dphi = C.neighbour_series(traj, lo, up)
        st = C.steady_offsets(dx, dy, lam)
        res = float(theory.compatibility_residual(st.dx_m, dphi, lam))
        out.append({
            "rank": rank, "lower": lo, "upper": up, "dphi": dphi,
            "dx_steady": st.dx_m, "dx_steady_over_lambda": st.dx_m / lam, "dy_steady": st.dy_m,
            "residual": res, "residual_over_lambda": res / lam,
            "band_excess": float(C.band_excess(st.dx_m, dphi, st.dy_m, amplitude_m, lam)),
            "settle_time": st.settle_time_s, "steady": st.steady, "order_stable": stable,
            "order_changed": changed,
        })
    return out


def _runs(sweep: xr.Dataset):
    """(run Dataset or None if failed) for every run of a sweep, flattened in grid order."""
    flat = sweep.stack(run=[d for d in sweep["run_failed"].dims]).transpose("run", ...)
    for k in range(flat.sizes["run"]):
        r = flat.isel(run=k)
        yield None if bool(r["run_failed"]) else r


def groups_dataset(sweeps: dict[int, xr.Dataset], amplitude_m: float) -> xr.Dataset:
    """Study dataset: one row per nearest-neighbour pair, and the trajectories per run."""
    lam = C.BODY_LENGTH_M / XI
    rows: list[dict] = []
    run_size, run_failed, xs, ys, phs = [], [], [], [], []
    time = next(iter(sweeps.values()))["time"].values
    nmax = max(sweeps)
    for n, sweep in sweeps.items():
        for r in _runs(sweep):
            k = len(run_size)
            run_size.append(n)
            run_failed.append(r is None)
            pad = np.full((time.size, nmax), np.nan)
            x, y, ph = pad.copy(), pad.copy(), np.full(nmax, np.nan)
            if r is not None:
                x[:, :n], y[:, :n] = r["x"].values, r["y"].values
                ph[:n] = r["phase"].values
                traj = C.trajectory(r, lam)
                for rec in group_records(traj, amplitude_m):
                    rows.append({"group_size": n, "run_index": k, **rec})
            xs.append(x)
            ys.append(y)
            phs.append(ph)

    def col(name, dtype=float):
        return np.array([row[name] for row in rows], dtype=dtype)

    nb = ("neighbour",)
    data = {}
    for name, (units, long_name) in NEIGHBOUR_FIELDS.items():
        dtype = int if units == "1" and name not in ("dx_steady_over_lambda", "residual_over_lambda") else float
        data[name] = (nb, col(name, dtype), {"units": units, "long_name": long_name})
    for name, long_name in NEIGHBOUR_FLAGS.items():
        data[name] = (nb, col(name, bool), {"long_name": long_name})
    data.update({
        "x": (("run", "time", "swimmer"), np.array(xs), {"units": "m", "long_name": "centre of mass x "
                                                                               "(NaN: no such swimmer)"}),
        "y": (("run", "time", "swimmer"), np.array(ys), {"units": "m", "long_name": "centre of mass y"}),
        "phase": (("run", "swimmer"), np.array(phs), {"units": "rad", "long_name": "gait phase phi"}),
        "run_group_size": ("run", np.array(run_size), {"units": "1", "long_name": "swimmers in the run"}),
        "run_failed": ("run", np.array(run_failed, bool), {"long_name": "the simulation failed"}),
    })
    return xr.Dataset(
        data,
        coords={
            "neighbour": ("neighbour", np.arange(len(rows)), {"units": "1"}),
            "run": ("run", np.arange(len(run_size)), {"units": "1"}),
            "swimmer": ("swimmer", np.arange(nmax), {"units": "1", "long_name": "swimmer id (initial stack, "
                                                                              "bottom to top)"}),
            "time": ("time", time, {"units": "s", "long_name": "time"}),
        },
        attrs={
            "title": "groups of 3 and 4 swimmers: nearest-neighbour dx vs dphi (paper Fig. 6)",
            "conventions": "neighbours by lateral order (mean y over the steady window); dx = x_upper - "
                           "x_lower, dphi = wrap(phi_upper - phi_lower); compatibility dx = lambda (dphi/2pi + n)",
            "waves_per_body": XI,
            "wavelength_m": lam,
            "amplitude_m": amplitude_m,
            "channel_width_3_m": CHANNEL_WIDTH_M[3],
            "channel_width_4_m": CHANNEL_WIDTH_M[4],
            "phases_3": "(0, dphi, 2 dphi) bottom to top",
            "phases_4": "each uniform in [0, 2 pi), numpy default_rng(run seed)",
            "duration_s": C.DURATION_S,
            "steady_rule": C.STEADY_RULE,
            "slope_method": C.SLOPE_METHOD,
        },
    )


def groups_summary(ds: xr.Dataset) -> dict:
    per = {}
    for n in (3, 4):
        sel = ds["group_size"].values == n
        runs = ds["run_group_size"].values == n
        res = ds["residual_over_lambda"].values[sel]
        fit = C.slope_fit(ds["dx_steady_over_lambda"].values[sel], ds["dphi"].values[sel])
        run_of = ds["run_index"].values[sel]
        changed = [bool(ds["order_changed"].values[sel][run_of == r][0]) for r in np.unique(run_of)]
        per[str(n)] = {
            "group_size": n,
            "channel_width_m": CHANNEL_WIDTH_M[n],
            "n_runs": int(runs.sum()),
            "n_failed": int(ds["run_failed"].values[runs].sum()),
            "n_neighbour_pairs": int(sel.sum()),
            "n_steady": int(ds["steady"].values[sel].sum()),
            "n_runs_lateral_order_changed": int(np.sum(changed)),
            "slope": fit.slope,
            "intercept": fit.intercept,
            "rms_residual_over_lambda": C.rms(res),
            "rms_residual_m": C.rms(ds["residual"].values[sel]),
            "max_abs_residual_over_lambda": float(np.max(np.abs(res))) if res.size else None,
            "rms_band_excess_over_lambda": C.rms(ds["band_excess"].values[sel] / ds.attrs["wavelength_m"]),
            "mean_dy_steady_over_2A": float(np.mean(ds["dy_steady"].values[sel]) / (2 * ds.attrs["amplitude_m"]))
            if sel.any() else None,
        }
    return {
        "per_group_size": per,
        "n_neighbour_pairs": int(ds.sizes["neighbour"]),
        "n_steady": int(ds["steady"].values.sum()),
        "neighbours": "by lateral order: mean y over the steady-state window at the end of the run",
        "residual": "RMS of theory.compatibility_residual / lambda over nearest-neighbour pairs",
        "steady_rule": C.STEADY_RULE,
        "slope_method": C.SLOPE_METHOD,
    }


@register("groups", paper_figure="6",
          description="Groups of 3 (d = 0.19 m, nine dphi) and 4 swimmers (d = 0.22 m, random phases), "
                      "xi = 1: nearest-neighbour steady dx vs dphi with the compatibility line.")
def run(config: StudyConfig) -> StudyResult:
    from ..plotting.groups import plot_groups

    three = C.run_points(config, "groups", "three",
                         C.sweep_function(n_swimmers=3, channel_width_m=CHANNEL_WIDTH_M[3]),
                         Grid(axes={"dphi_rad": [float(p) for p in phases(config.quick)]}, seed=config.seed))
    four = C.run_points(config, "groups", "four",
                        C.sweep_function(n_swimmers=4, channel_width_m=CHANNEL_WIDTH_M[4], random_phases=True),
                        Grid(axes={"waves_per_body": [XI]}, replicates=N_DRAWS[bool(config.quick)],
                             seed=config.seed))
    amp = C.run_points(config, "groups", "amplitude", C.free_amplitude,
                       Grid(axes={"waves_per_body": [XI]}, seed=config.seed))
    A = float(amp.dataset["amplitude"].values.ravel()[0])
    ds = groups_dataset({3: three.dataset, 4: four.dataset}, A)
    return StudyResult(dataset=ds, figure=plot_groups(ds), summary=groups_summary(ds))
