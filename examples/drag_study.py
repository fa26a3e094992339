"""A study of your own, outside the package: a pair's steady offset dx does not depend on the drag.

An example of docs/guide/studies.md, "Adding a study" (written by following that page, then kept
working by ``tests/test_example_study.py``).  Importing this file registers the study ``drag``;
``python examples/drag_study.py OUT`` runs it in quick mode (``--full`` for the full plan)::

    python examples/drag_study.py drag_results          # drag_results/drag.{nc,png,pdf,json}

Two 3-link swimmers (xi = 1) in the pair channel start straight, laterally in contact, at dx0 = 0,
with phase difference dphi, on the viscous ground with linear drag c per link at a few values around
the default.  The steady offset ``dx_steady / lambda`` at each c is compared with that at the smallest
c: the difference (wrapped to [-1/2, 1/2) lambda, the branches' period) should vanish if the
compatible state is set by geometry (contact), not by drag.  Its claims count with the paper's
(``Study.reference`` "paper", the default) in a reproduction run from a script that imports it.

It is its five parts and nothing else: ``plan``, ``dataset``, ``summary``, ``CLAIMS``, ``figure``.  The
registry stages it (the looks grow the plan's ``staged()`` grid while a claim is undecided) and decides
where and how its runs are executed.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import xarray as xr

from undulate import stats
from undulate.sweep import Grid
from undulate.studies import Claim, Study, StudyContext, Verdict, register, run_study, staged
from undulate.studies import _analysis as analysis
from undulate.studies._criteria import LINE_RMS_TOL, LINE_SLOPE_TOL, PAIR_CHANNEL_M
from undulate.studies._runners import BODY_LENGTH_M, PAIR_STOP, group_point

QUICK_DURATION_S = 12.0
"""Quick runs: 6 gait periods (the steady rule's window is 3), s."""
FULL_DURATION_S = 30.0
"""Full runs: 15 gait periods, as the paper's, s."""


@dataclass(frozen=True)
class Plan:
    """``dphi_rad`` (rad) at every ``drag_N_s_per_m`` (N s/m per link) for ``duration_s`` (s); the looks
    grow ``dphi_rad`` (quick 3, 5; full 5, 9, 17)."""

    dphi_rad: tuple[float, ...] = staged()
    drag_N_s_per_m: tuple[float, ...]
    duration_s: float


def plan(quick: bool) -> Plan:
    """Quick: 5 dphi in [0, pi/2], c in {1, 4}, 12 s; full: 17 dphi over [-pi, pi], c in {0.5 ... 8}, 30 s.
    Quick's dphi are 5 design points: a grid over [-pi/2, pi/2] would be 3 (-dphi is +dphi mirrored), and
    its first look's 2 would give the RMS no interval."""
    if quick:
        return Plan(tuple(float(p) for p in np.linspace(0.0, np.pi / 2, 5)), (1.0, 4.0), QUICK_DURATION_S)
    return Plan(tuple(float(p) for p in analysis.phase_grid(17)), (0.5, 1.0, 2.0, 4.0, 8.0), FULL_DURATION_S)


def dataset(ctx: StudyContext, p: Plan) -> xr.Dataset:
    """Run (or resume) the pair sweep over (drag, dphi); steady offsets per run (dims drag, dphi)."""
    grid = Grid(axes={"drag_N_s_per_m": list(p.drag_N_s_per_m), "dphi_rad": list(p.dphi_rad)},
                seed=ctx.seed)
    fn = functools.partial(group_point, n_swimmers=2, channel_width_m=PAIR_CHANNEL_M, stop=PAIR_STOP,
                           duration_s=p.duration_s)
    sim = ctx.sweep("sim", fn, grid)
    amp = float(ctx.lone_swimmer()["amplitude_m"])  # default drag: only the band excess reads it
    drag = sim["drag_N_s_per_m"].values.astype(float)
    dphi = sim["dphi_rad"].values.astype(float)
    failed = sim["run_failed"].isel(replicate=0).values.astype(bool)
    dims = ("drag", "dphi")
    variables, _ = analysis.collect_pairs(
        lambda idx: sim.isel(drag_N_s_per_m=idx[0], dphi_rad=idx[1], replicate=0),
        failed, dphi[None, :], BODY_LENGTH_M, amp, dims)
    return xr.Dataset(
        variables,
        coords={
            "drag": ("drag", drag, {"units": "N s/m", "long_name": "linear drag coefficient c per link"}),
            "dphi": ("dphi", dphi, {"units": "rad", "long_name": "phase difference phi_1 - phi_0"}),
        },
        attrs={"title": "pair steady offset against the drag coefficient", "channel_width_m": PAIR_CHANNEL_M,
               "duration_s": p.duration_s, "waves_per_body": 1.0, "steady_rule": analysis.STEADY_RULE},
    )


def _wrapped(x: np.ndarray) -> np.ndarray:
    return (x + 0.5) % 1.0 - 0.5


def summary(ds: xr.Dataset) -> dict:
    """Pure: per drag the compatibility slope and the RMS of the wrapped dx/lambda difference from the
    smallest drag."""
    y = ds["dx_steady_over_lambda"].values
    dphi = ds["dphi"].values
    per_drag = {}
    for i, c in enumerate(ds["drag"].values):
        fit = analysis.compatibility_fit(y[i], dphi, unwrap=True)
        per_drag[f"{c:g}"] = {"drag_N_s_per_m": float(c), "slope": fit.slope.to_dict(),
                              "n_steady": int(np.nansum(ds["steady"].values[i]))}
    diff = _wrapped(y[1:] - y[:1])
    # a design point is a drag and a |dphi|: the pair at -dphi is the one at +dphi mirrored, so the two are
    # resampled together (a cluster bootstrap), not counted as two independent points
    point = [f"{i} {k!r}" for i in range(diff.shape[0]) for k in analysis.abs_dphi_keys(dphi)]  # diff.ravel()'s order
    return {
        "per_drag": per_drag,
        "rms_shift_over_lambda": stats.rms(diff.ravel(), clusters=point).to_dict(),
        "n_runs": int(y.size),
        "n_failed": int(ds["run_failed"].values.sum()),
        "shift": "dx_steady/lambda at each drag minus that at the smallest, wrapped to [-1/2, 1/2)",
    }


E = stats.Estimate.from_dict


def _no_drag_shift(s: dict) -> Verdict:
    rms = E(s["rms_shift_over_lambda"])
    measured = f"RMS shift of dx/lambda with drag {rms:.3f} ({stats.interval_note(rms.level)})"
    if not rms.has_interval:
        return Verdict.none("no interval for the RMS shift", value=s["rms_shift_over_lambda"])
    return Verdict.of([rms.below(LINE_RMS_TOL, "RMS shift of dx/lambda")], measured, s["rms_shift_over_lambda"])


def _line_at_every_drag(s: dict) -> Verdict:
    slopes = {k: E(v["slope"]) for k, v in s["per_drag"].items()}
    measured = ", ".join(f"c = {k}: slope {e:.3f}" for k, e in slopes.items())
    if not all(e.has_interval for e in slopes.values()):
        return Verdict.none("no interval for a slope (too few steady runs)", measured)
    checks = [e.within(1 - LINE_SLOPE_TOL, 1 + LINE_SLOPE_TOL, f"slope at c = {k}") for k, e in slopes.items()]
    return Verdict.of(checks, measured, {k: v["slope"] for k, v in s["per_drag"].items()})


CLAIMS = (
    Claim("the steady dx of a pair does not depend on the drag coefficient",
          "(extension) the compatible offset is set by contact geometry, not by the medium",
          f"the upper 95 % bound of the RMS shift of dx/lambda from the smallest drag lies below {LINE_RMS_TOL}",
          _no_drag_shift),
    Claim("at every drag the steady dx follows the compatibility line",
          "(extension) steady dx agrees with dx = lambda dphi / 2 pi at every drag",
          f"the 95 % interval of the slope at every drag lies within 1 +- {LINE_SLOPE_TOL}",
          _line_at_every_drag),
)


def figure(ds: xr.Dataset):
    from undulate.plotting import new_figure, phase_axis

    fig = new_figure(5.0, 3.5)
    ax = fig.add_subplot()
    for c in ds["drag"].values:
        ax.plot(ds["dphi"].values, ds["dx_steady_over_lambda"].sel(drag=c).values, "o-", label=f"c = {c:g} N s/m")
    phase_axis(ax.xaxis)
    ax.set_xlabel(r"$\Delta\phi$")
    ax.set_ylabel(r"steady $\Delta x / \lambda$")
    ax.legend()
    return fig


register(Study(
    name="drag", plan=plan, dataset=dataset, summary=summary, claims=CLAIMS, figure=figure,
    description="Pairs of 3-link swimmers (xi = 1) at several linear drag coefficients: steady dx/lambda vs dphi "
                "per drag, and its shift with drag."))


if __name__ == "__main__":
    import argparse
    from pathlib import Path

    ap = argparse.ArgumentParser(description="Run the example study 'drag'.")
    ap.add_argument("out", type=Path, help="output folder")
    ap.add_argument("--full", action="store_true", help="the full plan (default: quick)")
    args = ap.parse_args()
    print(f"wrote {run_study('drag', args.out, quick=not args.full)}")
