"""Reproduction: MuJoCo 4.0.0's sparse Newton solver returns wrong accelerations on a jammed pack.

    python explorations/sparse_newton_repro.py

Why ``pyproject.toml`` pins MuJoCo to 3.17.0 (where this script finds no
disagreement in 1500 steps; run it under a candidate release before lifting
the pin; ``benchmarks/bench_solvers.py`` checks today's model the same way).
Before the pin, it was why ``SimOptions.solver = "auto"`` never picked Newton for scenes with a
sparse constraint Jacobian (>= 60 degrees of freedom), and why the time-step
rule cannot rely on it to make dense scenes cheap.

The scene is the packing study's jammed pack as it was before the physics
issue (one capsule per link, 2 ms steps, MuJoCo's approximate constraint
diagonal): 50 three-link swimmers in the short channel at rho~ = 3,
phi_max = pi.  The script steps it with ``mj_step`` under the sparse Newton
solver and, at every step, solves the same state with the dense-Jacobian
Newton solver.  At the first step where the two disagree it solves the
state with CG and PGS too and reports, for each solver, the accelerations'
distance from dense Newton and the *true* optimality residual
``|M (qacc - qacc_smooth) - J' f|`` (recomputed here from the returned
forces, not the solver's own bookkeeping).

Measured with MuJoCo 4.0.0 (this machine): the first disagreement is at
t = 1.568 s (step 784, 119 contacts).  Sparse Newton stops after 3
iterations reporting a gradient of 7e-15, yet its true residual is 1.9e3 and
one contact force is 1.9e3 N where dense Newton, CG and PGS agree on at most
11.5 N (their accelerations agree to 0.01-0.02); the sparse trajectory is
reset by MuJoCo for bad accelerations 12 steps later.  Raising the iteration
limit, zero tolerance, other line-search settings or disabling islands do not
change the sparse answer.
"""

from __future__ import annotations

import copy
import math

import mujoco
import numpy as np

from undulate import Channel, ContactModel, Scene, SimOptions, SwimmerGeometry
from undulate.simulation import compile_scene

A_M = 0.0525  # free-swimmer amplitude used for the channel width, m
N = 50


def jammed_pack() -> Scene:
    u = np.random.default_rng([0, 0]).random(N)
    width = 2 * A_M * N / 3.0
    return Scene(phases_rad=tuple(math.pi * u), geometry=SwimmerGeometry(collision_segments=1),
                 channel=Channel(width_m=width, end_walls_m=1.1 * 0.54), lateral_gap_m=width / N - 0.015,
                 contact=ContactModel())


def main(max_steps: int = 1500) -> None:
    dt = 0.002
    cs = compile_scene(jammed_pack(), SimOptions(duration_s=1.0, timestep_s=dt, solver="newton"))
    m = cs.model
    m.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_DIAGEXACT)  # the model as it was
    m.opt.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE
    dense = copy.copy(m)
    dense.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    d, dd = mujoco.MjData(m), mujoco.MjData(dense)
    mujoco.mj_forward(m, d)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(m, spec))
    u = cs.controls(np.arange(max_steps) * dt)
    for k in range(max_steps):
        d.ctrl[:] = u[k]
        mujoco.mj_getState(m, d, state, spec)
        mujoco.mj_setState(dense, dd, state, spec)
        dd.ctrl[:] = u[k]
        mujoco.mj_forward(dense, dd)
        mujoco.mj_step(m, d)
        if np.abs(d.qacc - dd.qacc).max() > 1e-3 * max(1.0, np.abs(dd.qacc).max()):
            break
    else:
        print(f"no disagreement in {max_steps} steps")
        return
    print(f"first disagreement at step {k} (t = {k * dt:.3f} s), {dd.ncon} contacts, mujoco {mujoco.__version__}")
    ref = dd.qacc.copy()

    def solve(solver, jacobian, iterations=100):
        mm = copy.copy(m)
        mm.opt.solver, mm.opt.jacobian, mm.opt.iterations = solver, jacobian, iterations
        x = mujoco.MjData(mm)
        mujoco.mj_setState(mm, x, state, spec)
        x.ctrl[:] = u[k]
        mujoco.mj_forward(mm, x)
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(mm, x, M)
        J = np.zeros((x.nefc, m.nv))
        if mujoco.mj_isSparse(mm):
            mujoco.mju_sparse2dense(J, x.efc_J, x.efc_J_rownnz, x.efc_J_rowadr, x.efc_J_colind)
        else:
            J[:] = x.efc_J.reshape(x.nefc, m.nv)
        residual = M @ (x.qacc - x.qacc_smooth) - J.T @ x.efc_force[:x.nefc]
        reported = x.solver[0].gradient if x.solver_niter[0] else float("nan")
        return x, np.abs(residual).max(), reported

    S, Jt = mujoco.mjtSolver, mujoco.mjtJacobian
    print(f"{'solver':22s} {'iterations':>10s} {'max|qacc - dense Newton|':>25s} {'true residual':>14s} "
          f"{'reported gradient':>18s} {'max contact force N':>20s}")
    for name, sol, jac, it in [("Newton, dense", S.mjSOL_NEWTON, Jt.mjJAC_DENSE, 100),
                               ("Newton, sparse", S.mjSOL_NEWTON, Jt.mjJAC_SPARSE, 100),
                               ("Newton, sparse, 1000 it", S.mjSOL_NEWTON, Jt.mjJAC_SPARSE, 1000),
                               ("CG, sparse, 10000 it", S.mjSOL_CG, Jt.mjJAC_SPARSE, 10000),
                               ("PGS, 10000 it", S.mjSOL_PGS, Jt.mjJAC_DENSE, 10000)]:
        x, res, grad = solve(sol, jac, it)
        print(f"{name:22s} {int(x.solver_niter[0]):10d} {np.abs(x.qacc - ref).max():25.3g} {res:14.3g} "
              f"{grad:18.3g} {x.efc_force[:x.nefc].max():20.3g}")


if __name__ == "__main__":
    mujoco.set_mju_user_warning(lambda msg: None)
    main()
