"""A toy staged study for tests/test_staged_verdicts.py: real sweeps of a real (MuJoCo) pendulum.

Importable by a subprocess (the kill-and-resume test).  Each run's start angle is drawn from its
seed, uniform in [-1, 1] rad; the study's one claim asks whether the mean start angle lies in
``REGION`` (set by the test), judged on its interval.  Stages: 6, 12, 24 points (nested).
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import xarray as xr  # noqa: E402

import sweep_funcs  # noqa: E402
from undulate import stats  # noqa: E402
from undulate.studies import Claim, Study, Verdict, register  # noqa: E402
from undulate.sweep import Grid  # noqa: E402

REGION = (-2.0, 2.0)
MIN_POINTS = 2
"""Fewer runs than this give the claim ``no result`` (set by a test)."""
STAGE_POINTS = (6, 12, 24)
KILL_AT = 0.1 + 0.01 * 9  # a point of stage 2 only


def damping(n: int) -> tuple[float, ...]:
    return tuple(round(0.1 + 0.01 * i, 6) for i in range(n))


def start_angle(point: dict, seed: int) -> xr.Dataset:
    """:func:`sweep_funcs.pendulum` for 0.1 s; kills its process at ``KILL_AT`` once when
    ``STAGED_KILL_MARKER`` names a file that does not exist yet (it is created first)."""
    marker = os.environ.get("STAGED_KILL_MARKER")
    if marker and abs(point["damping_Nms"] - KILL_AT) < 1e-9 and not Path(marker).exists():
        Path(marker).write_text("killed")
        os.kill(os.getpid(), signal.SIGKILL)
    return sweep_funcs.pendulum({**point, "duration_s": 0.1}, seed)


def dataset(ctx, plan):
    grid = Grid(axes={"damping_Nms": list(plan), "length_m": [0.5]}, seed=ctx.config.seed)
    sim = ctx.sweep("sim", start_angle, grid)
    a = sim["angle"].isel(time=0, length_m=0, replicate=0).drop_vars("seed")
    return xr.Dataset({"start_angle": ("run", a.values, {"units": "rad"})})


def summary(ds):
    return {"mean_start_angle": stats.mean(ds["start_angle"].values).to_dict()}


def _judge(s):
    m = stats.Estimate.from_dict(s["mean_start_angle"])
    if m.n < MIN_POINTS:
        return Verdict.none(f"{m.n} runs, fewer than {MIN_POINTS}", value=s)
    return Verdict.of([m.within(*REGION, "mean start angle (rad)")], f"mean start angle {m:.3f} rad", s)


def _figure(ds):
    fig, ax = plt.subplots()
    ax.plot(ds["start_angle"].values, ".")
    return fig


CLAIM = Claim("the mean start angle lies in REGION", "toy", "interval inside REGION", _judge)
register(Study(name="_staged", description="toy staged study", plan=lambda quick: damping(STAGE_POINTS[-1]),
               stages=lambda quick: tuple(damping(n) for n in STAGE_POINTS), dataset=dataset, summary=summary,
               claims=(CLAIM,), figure=_figure))
register(Study(name="_whole", description="the same study in one stage",
               plan=lambda quick: damping(STAGE_POINTS[-1]), dataset=dataset, summary=summary, claims=(CLAIM,),
               figure=_figure))
