"""Constraint solvers on the jammed packs, today's physics (measured, never asserted).

    python benchmarks/bench_solvers.py [--duration 3] [--check-steps 1500]

The packing study's two scenes of ``bench_packing.py`` (50 three-link
swimmers, rho~ = 3 / phi_max = pi and rho~ = 5.5 / phi_max = 2 pi), with the
default model (two capsules per link, exact constraint diagonal, the
time-step rule's step, the packing study's sensors).  For each solver
configuration -- CG (sparse Jacobian), Newton with the sparse Jacobian,
Newton with the dense Jacobian -- it reports compute per simulated second
(one ``mujoco.rollout`` on one core), steady (t >= 2 s) and start-up
interpenetration, and whether the run diverged (MuJoCo reset the state).

``--check-steps K`` then steps the rho~ = 3 scene K steps with sparse Newton
and, at every step, solves the same state with dense Newton (the reference):
the first step whose accelerations disagree by more than 1e-3 of their scale
is printed, or "no disagreement".  This is the test that found MuJoCo 4.0.0's
sparse-Newton failure (``explorations/sparse_newton_repro.py`` has the
minimal case); run it under each MuJoCo release considered.
"""

from __future__ import annotations

import argparse
import copy
import math

import mujoco
import numpy as np

from undulate import SimOptions, SwimmerGeometry
from undulate.scene import build
from undulate.simulation import compile_scene, resolve_options
from undulate.studies._runners import lone_swimmer

N = 50
SCENES = {"rho3_pi": (3.0, math.pi), "rho5.5_2pi": (5.5, 2 * math.pi)}
S, J = mujoco.mjtSolver, mujoco.mjtJacobian
CONFIGS = {
    "CG, sparse": (S.mjSOL_CG, J.mjJAC_SPARSE),
    "Newton, sparse": (S.mjSOL_NEWTON, J.mjJAC_SPARSE),
    "Newton, dense": (S.mjSOL_NEWTON, J.mjJAC_DENSE),
}


def pack(rho: float, phi_max: float, amplitude_m: float):
    from bench_packing import pack_scene  # the benchmark's scene, one definition
    sc = pack_scene(rho, phi_max, amplitude_m, segments=SwimmerGeometry().collision_segments)
    opt = resolve_options(sc, SimOptions(duration_s=1.0))
    cs = compile_scene(sc, opt)
    lean = build(sc, opt.timestep_s, pair_sensors=False)  # what the packing study records
    lean.model.opt.disableflags = cs.model.opt.disableflags
    lean.model.opt.integrator = cs.model.opt.integrator
    return lean, opt.timestep_s


def run(cs, dt: float, duration_s: float, solver, jacobian) -> dict:
    """``bench_packing.run_once`` (one rollout of the whole run) under one solver configuration."""
    from bench_packing import run_once

    m = cs.model
    saved = m.opt.solver, m.opt.jacobian
    m.opt.solver, m.opt.jacobian = solver, jacobian
    try:
        r = run_once(cs, dt, duration_s)
    finally:
        m.opt.solver, m.opt.jacobian = saved
    return dict(s_per_sim_s=r["wall_s_per_sim_s"], us_per_step=r["us_per_step"], pen_start_mm=r["pen_startup_mm"],
                pen_steady_mm=r["pen_steady_mm"], diverged=r["diverged"])


def first_disagreement(cs, dt: float, steps: int) -> str:
    m = copy.copy(cs.model)
    m.opt.solver, m.opt.jacobian = S.mjSOL_NEWTON, J.mjJAC_SPARSE
    dense = copy.copy(m)
    dense.opt.jacobian = J.mjJAC_DENSE
    d, dd = mujoco.MjData(m), mujoco.MjData(dense)
    mujoco.mj_forward(m, d)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(m, spec))
    u = cs.controls(np.arange(steps) * dt)
    worst = 0.0
    for k in range(steps):
        d.ctrl[:] = u[k]
        mujoco.mj_getState(m, d, state, spec)
        mujoco.mj_setState(dense, dd, state, spec)
        dd.ctrl[:] = u[k]
        mujoco.mj_forward(dense, dd)
        mujoco.mj_step(m, d)
        rel = np.abs(d.qacc - dd.qacc).max() / max(1.0, np.abs(dd.qacc).max())
        worst = max(worst, rel)
        if rel > 1e-3:
            return (f"first disagreement at step {k} (t = {k * dt:.3f} s, {dd.ncon} contacts): "
                    f"max contact force sparse {d.efc_force[:d.nefc].max():.3g} N, "
                    f"dense {dd.efc_force[:dd.nefc].max():.3g} N")
    return f"no disagreement in {steps} steps (largest relative qacc difference {worst:.2g})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=3.0, help="simulated seconds per run")
    ap.add_argument("--check-steps", type=int, default=1500, help="steps of the sparse/dense check (0: skip)")
    args = ap.parse_args()
    mujoco.set_mju_user_warning(lambda msg: None)
    amp = float(lone_swimmer({}, 0)["amplitude_m"])
    print(f"mujoco {mujoco.__version__}; A = {amp * 1e3:.2f} mm; {args.duration:g} s per run, {N} swimmers")
    print(f"{'scene':11s} {'solver':15s} {'dt ms':>6s} {'s/sim s':>8s} {'us/step':>8s} "
          f"{'pen start':>9s} {'pen steady':>10s} {'diverged':>8s}")
    for name, (rho, phi) in SCENES.items():
        cs, dt = pack(rho, phi, amp)
        for label, (sol, jac) in CONFIGS.items():
            r = run(cs, dt, args.duration, sol, jac)
            print(f"{name:11s} {label:15s} {dt * 1e3:6.3g} {r['s_per_sim_s']:8.3f} {r['us_per_step']:8.0f} "
                  f"{r['pen_start_mm']:8.2f}m {r['pen_steady_mm']:9.2f}m {str(r['diverged']):>8s}", flush=True)
    if args.check_steps:
        cs, dt = pack(*SCENES["rho3_pi"], amp)
        print("sparse vs dense Newton, rho3_pi:", first_disagreement(cs, dt, args.check_steps))


if __name__ == "__main__":
    main()
