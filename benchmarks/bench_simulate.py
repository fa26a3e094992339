"""Simulator throughput (measured, never asserted).

    python benchmarks/bench_simulate.py [--quick]

Reports, on this machine:
* wall time per simulated second and per step for 2, 4 and 50 three-link
  swimmers through :func:`undulate.simulate` (recording at 20 Hz), and the
  ratio to a bare ``mujoco.rollout`` of the same compiled model without
  recording;
* the compute time of a 30 s pair run;
* whole-process time of ``undulate simulate`` for a 300 s pair run against a
  bare MuJoCo script of the same scene (both as fresh processes);
* the cost and physics of the collision geometry: capsules (default) against
  boxes for the 50-swimmer scene and a pair (penetration, final dx/lambda);
* the time-step convergence of the pair's final dx/lambda.

The jammed 50-swimmer packs the packing study actually runs are benchmarked
in ``bench_packing.py`` (the scene here at rho~ = 0.7 barely touches).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import mujoco
import numpy as np
from mujoco import rollout

from undulate import Channel, Scene, SimOptions, simulate, simulate_batch
from undulate.observables import neighbour_offsets
from undulate.simulation import compile_scene, controls, resolve_options


def group_scene(n: int, seed: int = 0) -> Scene:
    rng = np.random.default_rng(seed)
    phases = tuple(rng.uniform(0, math.pi, n))
    if n == 2:
        return Scene(phases_rad=(0.0, math.pi / 2))
    if n == 50:  # the packing study's short channel at rho~ = 2AN/Y = 0.7, swimmers spread evenly
        width = 2 * 0.052 * n / 0.7
        gap = (width - n * 0.015) / n
        return Scene(phases_rad=phases, channel=Channel(width_m=width, end_walls_m=1.1 * 0.54),
                     lateral_gap_m=gap)
    return Scene(phases_rad=phases, channel=Channel(width_m=0.22))


def bare_rollout_us_per_step(cs, nsteps: int) -> float:
    m = cs.model
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    s0 = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(m, d, s0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    u = controls(cs, np.arange(nsteps) * m.opt.timestep)[None]
    rollout.rollout(m, d, s0, u[:, :100])
    best = math.inf
    for _ in range(3):
        t = time.perf_counter()
        rollout.rollout(m, d, s0, u)
        best = min(best, time.perf_counter() - t)
    return best / nsteps * 1e6


def timed_simulate(scene: Scene, opt: SimOptions, repeat: int = 3) -> tuple[float, object]:
    best, ds = math.inf, None
    for _ in range(repeat):
        t = time.perf_counter()
        ds = simulate(scene, opt)
        best = min(best, time.perf_counter() - t)
    return best, ds


def throughput(quick: bool) -> None:
    print("== throughput (implicitfast, dt = 2 ms, recording at 20 Hz) ==")
    for n in (2, 4, 50):
        sc = group_scene(n)
        dur = 10.0 if n == 50 else 30.0
        if quick:
            dur /= 5
        opt = resolve_options(sc, SimOptions(duration_s=dur))
        w, _ = timed_simulate(sc, opt, repeat=1 if n == 50 else 3)
        bare = bare_rollout_us_per_step(compile_scene(sc, opt), opt.n_steps)
        per_step = w / opt.n_steps * 1e6
        print(f"{n:3d} swimmers (dt {opt.timestep_s * 1e3:.3g} ms): {w / dur * 1e3:8.2f} ms wall per simulated s   "
              f"{per_step:7.1f} us/step   "
              f"bare rollout {bare:7.1f} us/step   ratio {per_step / bare:5.2f}")
    w, _ = timed_simulate(group_scene(2), SimOptions(duration_s=30.0))
    print(f"30 s pair run: {w:.3f} s compute (compile + rollout + dataset)")


BARE_SCRIPT = textwrap.dedent(
    """
    import math, numpy as np, mujoco
    from mujoco import rollout
    from undulate.params import Scene, SimOptions
    from undulate.scene import build
    from undulate.simulation import resolve_options
    sc = Scene(phases_rad=(0.0, math.pi / 2))
    opt = resolve_options(sc, SimOptions(duration_s=300.0))
    cs = build(sc, opt.timestep_s)
    m = cs.model; d = mujoco.MjData(m); mujoco.mj_forward(m, d)
    m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_WARMSTART)
    s0 = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(m, d, s0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    u = cs.controls(np.arange(opt.n_steps) * opt.timestep_s)[None]
    state, sens = rollout.rollout(m, d, s0, u)
    np.save("bare.npy", state[0, ::25])
    """
)


def cli_vs_bare(quick: bool) -> None:
    print("== whole process: `undulate simulate` 300 s pair vs a bare MuJoCo script ==")
    with tempfile.TemporaryDirectory() as tmp:
        Path(tmp, "bare.py").write_text(BARE_SCRIPT)
        reps = 1 if quick else 3

        def best(cmd):
            b = math.inf
            for _ in range(reps):
                t = time.perf_counter()
                subprocess.run(cmd, cwd=tmp, check=True, capture_output=True)
                b = min(b, time.perf_counter() - t)
            return b

        bare = best([sys.executable, "bare.py"])
        cli = best([sys.executable, "-m", "undulate.cli", "simulate", "--phases", "0,90", "--duration", "300",
                    "--out", "run.nc", "--quiet"])
    print(f"bare script {bare:.2f} s, CLI {cli:.2f} s, ratio {cli / bare:.2f}")


def collision_geometry(quick: bool) -> None:
    """Capsules vs boxes: cost per step and the physics they give."""
    print("== collision geometry: capsule (default) vs box links ==")
    for n in (2, 50):
        res = {}
        for shape in ("capsule", "box"):
            sc = group_scene(n)
            sc = dataclasses.replace(sc, geometry=dataclasses.replace(sc.geometry, collision_shape=shape))
            opt = resolve_options(sc, SimOptions(duration_s=4.0 if n == 50 else 30.0))
            us = bare_rollout_us_per_step(compile_scene(sc, opt), min(opt.n_steps, 2000))
            ds = simulate(sc, opt)
            steady = ds["penetration"].sel(time=slice(opt.duration_s / 3, None))
            off = neighbour_offsets(ds)
            dx = float(off["dx"].isel(time=slice(-20, None)).mean()) / sc.wavelength_m
            res[shape] = (us, float(steady.max()) * 1e3, dx)
        line = "   ".join(f"{k}: {v[0]:7.1f} us/step, steady penetration {v[1]:.2f} mm" for k, v in res.items())
        extra = (f"   final dx/lambda capsule {res['capsule'][2]:.4f}, box {res['box'][2]:.4f}" if n == 2 else "")
        print(f"{n:3d} swimmers: {line}{extra}")


def convergence(quick: bool) -> None:
    print("== time-step convergence, pair dphi = 90 deg, final dx/lambda ==")
    sc = group_scene(2)
    prev = None
    for dt in (0.004, 0.002, 0.001) + (() if quick else (0.0005,)):
        ds = simulate(sc, SimOptions(duration_s=30.0, timestep_s=dt))
        off = neighbour_offsets(ds)
        v = float(off["dx"].isel(time=slice(-20, None)).mean()) / sc.wavelength_m
        diff = "" if prev is None else f"   change {v - prev:+.5f}"
        print(f"dt = {dt * 1e3:4.1f} ms: dx/lambda = {v:.5f}{diff}")
        prev = v


def batching(quick: bool) -> None:
    """One process, MuJoCo's rollout thread pool over a batch of scenes vs one scene at a time."""
    print("== in-process batching: 200 pair runs of 10 s (simulate_batch, 2 rollout threads) ==")
    n = 40 if quick else 200
    scenes = [Scene(phases_rad=(0.0, float(d))) for d in np.linspace(-math.pi, math.pi, n)]
    opt = SimOptions(duration_s=10.0, sample_rate_hz=10)
    simulate(scenes[0], opt)
    t = time.perf_counter()
    one = [simulate(s, opt) for s in scenes]
    serial = time.perf_counter() - t
    t = time.perf_counter()
    batch = simulate_batch(scenes, opt, nthread=2)
    batched = time.perf_counter() - t
    same = all(np.array_equal(a["x"].values, b["x"].values) for a, b in zip(one, batch))
    print(f"serial {n / serial:.1f} runs/s, batched {n / batched:.1f} runs/s, speed-up {serial / batched:.2f}x, "
          f"identical: {same}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    throughput(args.quick)
    batching(args.quick)
    convergence(args.quick)
    collision_geometry(args.quick)
    cli_vs_bare(args.quick)


if __name__ == "__main__":
    main()
