"""The time around the physics: three per-call costs, each against what it replaced (measured, never asserted).

    python benchmarks/bench_overheads.py [--repeat 5]

Each pair is alternated in one process, best of ``--repeat``:

* **rollout call**: one control period of a closed-loop pair (15 steps at the
  rule's 0.667 ms) through ``mujoco.rollout.Rollout.rollout`` with its
  argument checks and tiling, against the same call with ``skip_checks``
  (what :class:`undulate.simulation._WarmRollout` does when every array
  already has rollout's exact shape).  A closed-loop run pays it once per
  control period (100 Hz).
* **period average**: :func:`undulate.observables.period_average` of a 30 s
  pair's offsets against xarray's ``groupby("period").mean("time")`` (what it
  replaced; bitwise the same, tested).  A pair run takes several.
* **animation**: one of the report's animations (24 s at 10 Hz, 241 frames)
  drawn by blitting against a full matplotlib redraw of every frame (what
  :func:`undulate.animation.animate` did; same bytes out, tested).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

from undulate import Channel, Scene, SimOptions, simulate
from undulate.observables import neighbour_offsets, period_average, period_average_groupby
from undulate.simulation import compile_scene, resolve_options


def _best(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def rollout_calls(repeat: int, calls: int = 2000) -> tuple[float, float]:
    """µs per call: checked, skip_checks."""
    sc = Scene(phases_rad=(0.0, 1.0))
    cs = compile_scene(sc, resolve_options(sc, SimOptions(duration_s=1.0)))
    m, d = cs.model, mujoco.MjData(cs.model)
    mujoco.mj_forward(m, d)
    nstate = mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    s0 = np.empty((1, nstate))
    mujoco.mj_getState(m, d, s0[0], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    k = 15
    u, w = np.zeros((1, k, m.nu)), np.zeros((1, m.nv))
    st, sd = np.empty((1, k, nstate)), np.empty((1, k, m.nsensordata))
    r = rollout.Rollout(nthread=0)

    def checked():
        for _ in range(calls):
            r.rollout(m, d, s0, u, nstep=k, initial_warmstart=w, state=st, sensordata=sd)

    def skipped():
        for _ in range(calls):
            r.rollout([m], [d], s0, u, skip_checks=True, nstep=k, initial_warmstart=w, state=st, sensordata=sd)

    a, b = [], []
    for _ in range(repeat):
        a.append(_best(checked, 1))
        b.append(_best(skipped, 1))
    r.close()
    return 1e6 * min(a) / calls, 1e6 * min(b) / calls


def period_averages(repeat: int, calls: int = 50) -> tuple[float, float]:
    """ms per call: xarray groupby, NumPy slices."""
    ds = simulate(Scene(phases_rad=(0.0, 1.0), dx0_m=0.05), SimOptions(duration_s=30.0))
    dx = neighbour_offsets(ds)["dx"]
    a = b = float("inf")
    for _ in range(repeat):
        a = min(a, _best(lambda: [period_average_groupby(dx, 2.0) for _ in range(calls)], 1))
        b = min(b, _best(lambda: [period_average(dx, 2.0) for _ in range(calls)], 1))
    return 1e3 * a / calls, 1e3 * b / calls


def _full_redraw(ds, out: Path) -> None:
    """The animation as it was drawn before blitting: matplotlib's PillowWriter, a full draw a frame."""
    from matplotlib import animation

    from undulate.animation import _Frame, _Recording, _stage

    run = _Recording(ds, 1)
    fig, ax, walls = _stage(ds, run, 70, "title")
    frame = _Frame(ax, run, walls)
    writer = animation.PillowWriter(fps=20)
    with writer.saving(fig, str(out), 70):
        for i in range(len(run.times)):
            frame.draw(i)
            writer.grab_frame()


def animations(repeat: int) -> tuple[float, float]:
    """s per animation: full redraw, blitted."""
    from undulate.animation import animate
    from undulate.reproduce import ANIMATIONS

    _, _, kw, dur = ANIMATIONS[1]
    sc = Scene(phases_rad=tuple(np.radians(kw["phases_deg"])), channel=Channel(width_m=kw["channel_width_m"]))
    ds = simulate(sc, SimOptions(duration_s=dur, sample_rate_hz=10))
    tmp = Path(tempfile.mkdtemp())
    a = b = float("inf")
    for _ in range(max(1, repeat // 2)):
        a = min(a, _best(lambda: _full_redraw(ds, tmp / "full.gif"), 1))
        b = min(b, _best(lambda: animate(ds, tmp / "blit.gif", fps=20, dpi=70, title="title"), 1))
    return a, b


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="alternating repeats (best kept)")
    args = ap.parse_args()
    c, s = rollout_calls(args.repeat)
    print(f"rollout call, one control period (15 steps): checked {c:.1f} us, skip_checks {s:.1f} us "
          f"(saved {c - s:.1f} us a call, {100 * (c - s) / c:.0f} %)")
    g, n = period_averages(args.repeat)
    print(f"period average of a 30 s pair's dx: xarray groupby {g:.2f} ms, NumPy slices {n:.2f} ms ({g / n:.1f}x)")
    f, b = animations(args.repeat)
    print(f"report animation (241 frames): full redraw {f:.2f} s, blitted {b:.2f} s ({f / b:.1f}x)")


if __name__ == "__main__":
    main()
