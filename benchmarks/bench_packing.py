"""The workload users actually run: jammed 50-swimmer packs (measured, never asserted).

    python benchmarks/bench_packing.py [--duration 10] [--repeat 1]

The packing study's scenes: 50 three-link swimmers in the short channel
(end walls 1.1 L apart), phases uniform in [0, phi_max] (draw 0 of seed 0),
channel width from rho~ = 2 A N / Y with A the measured free-swimmer
amplitude, swimmers spread evenly.  Two scenes: rho~ = 3, phi_max = pi
(around the threshold) and rho~ = 5.5, phi_max = 2 pi (deep in the jam).

Each scene runs under two configurations, alternated in one process:

* ``before``: the model before the physics issue: one capsule per link,
  2 ms steps, MuJoCo's approximate constraint diagonal, the 49
  swimmer-swimmer contact sensors;
* ``after``: the defaults now (two capsules per link, exact diagonal, the
  time-step rule's step), recording only what the packing study uses (no
  pair-force sensors).

Reported per scene and configuration: compute per simulated second and per
step (one ``mujoco.rollout`` of the whole run on one core), steady (t >= 2 s)
and start-up (t < 2 s) interpenetration, whether the run diverged, and the
per-step breakdown from MuJoCo's timers: collision (broad + narrow phase),
constraint build, solver, sensors (from a run with sensors disabled) and the
rest (kinematics, inertia, actuation, velocity, integration).
"""

from __future__ import annotations

import argparse
import math
import time

import mujoco
import numpy as np
from mujoco import rollout

from undulate import Channel, Scene, SimOptions, SwimmerGeometry
from undulate.scene import build
from undulate.simulation import compile_scene, resolve_options
from undulate.studies._runners import lone_swimmer

SCENES = {"rho3_pi": (3.0, math.pi), "rho5.5_2pi": (5.5, 2 * math.pi)}
N = 50


def pack_scene(rho: float, phi_max: float, amplitude_m: float, segments: int) -> Scene:
    u = np.random.default_rng([0, 0]).random(N)
    width = 2 * amplitude_m * N / rho
    geo = SwimmerGeometry(collision_segments=segments)
    return Scene(phases_rad=tuple(phi_max * u), geometry=geo,
                 channel=Channel(width_m=width, end_walls_m=1.1 * geo.length_m),
                 lateral_gap_m=width / N - geo.width_m)


def compiled(config: str, scene_args: tuple) -> tuple:
    """(model, index, dt) for a configuration."""
    rho, phi, amp = scene_args
    if config == "before":
        sc = pack_scene(rho, phi, amp, segments=1)
        opt = SimOptions(duration_s=1.0, timestep_s=0.002)
        cs = compile_scene(sc, opt)
        cs.model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_DIAGEXACT)
        return cs, 0.002
    sc = pack_scene(rho, phi, amp, segments=SwimmerGeometry().collision_segments)
    opt = resolve_options(sc, SimOptions(duration_s=1.0))
    cs = compile_scene(sc, opt)
    lean = build(sc, opt.timestep_s, pair_sensors=False)  # what the packing study records
    lean.model.opt.disableflags = cs.model.opt.disableflags
    lean.model.opt.solver = cs.model.opt.solver
    lean.model.opt.integrator = cs.model.opt.integrator
    return lean, opt.timestep_s


def run_once(cs, dt: float, duration: float, sensors: bool = True) -> dict:
    m = cs.model
    if not sensors:
        m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    s0 = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS))
    mujoco.mj_getState(m, d, s0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
    n = int(round(duration / dt))
    u = cs.controls(np.arange(n) * dt)[None]
    t0 = time.perf_counter()
    st, sd = rollout.rollout(m, d, s0, u)
    wall = time.perf_counter() - t0
    if not sensors:
        m.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_SENSOR)
    tm = {k: d.timer[getattr(mujoco.mjtTimer, "mjTIMER_" + k)].duration / n * 1e6
          for k in ("STEP", "POS_COLLISION", "POS_MAKE", "CONSTRAINT")}
    out = dict(wall_s_per_sim_s=wall / duration, us_per_step=wall / n * 1e6, timers=tm)
    if sensors:
        md = cs.index.sens_mindist
        depth = np.where(sd[0, :, md] > 0, np.maximum(0.0, -sd[0, :, md + 1]), 0.0)
        t = np.arange(1, n + 1) * dt
        out["pen_startup_mm"] = float(depth[t < 2.0].max()) * 1e3
        out["pen_steady_mm"] = float(depth[t >= 2.0].max()) * 1e3 if (t >= 2.0).any() else float("nan")
        reset = np.abs(st[0, :, 0] - t) > 0.5 * dt
        out["diverged"] = bool(reset.any() or not np.isfinite(st).all() or depth.max() > 0.0075)
        out["contacts"] = int(d.ncon)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=10.0, help="simulated seconds per run")
    ap.add_argument("--repeat", type=int, default=1, help="alternating repeats (best time kept)")
    args = ap.parse_args()
    amp = float(lone_swimmer({}, 0)["amplitude_m"])
    print(f"free-swimmer amplitude A = {amp * 1e3:.2f} mm; {args.duration:g} s per run, {N} swimmers")
    for name, (rho, phi) in SCENES.items():
        results: dict[str, dict] = {}
        for _ in range(args.repeat):
            for config in ("before", "after"):
                cs, dt = compiled(config, (rho, phi, amp))
                r = run_once(cs, dt, args.duration)
                bare = run_once(cs, dt, min(args.duration, 2.0), sensors=False)
                r["sensor_us"] = max(0.0, r["timers"]["STEP"] - bare["timers"]["STEP"])
                r["dt_ms"] = dt * 1e3
                best = results.get(config)
                if best is None or r["wall_s_per_sim_s"] < best["wall_s_per_sim_s"]:
                    results[config] = r
        print(f"\n== {name}: rho~ = {rho:g}, phi_max = {phi / math.pi:g} pi ==")
        print(f"{'config':8s} {'dt ms':>6s} {'s/sim s':>8s} {'us/step':>8s} {'collision':>9s} {'build':>6s} "
              f"{'solver':>7s} {'sensors':>7s} {'rest':>6s} {'pen start':>9s} {'pen steady':>10s} {'diverged':>8s}")
        for config, r in results.items():
            tm = r["timers"]
            rest = tm["STEP"] - tm["POS_COLLISION"] - tm["POS_MAKE"] - tm["CONSTRAINT"] - r["sensor_us"]
            print(f"{config:8s} {r['dt_ms']:6.3g} {r['wall_s_per_sim_s']:8.3f} {r['us_per_step']:8.0f} "
                  f"{tm['POS_COLLISION']:9.0f} {tm['POS_MAKE']:6.0f} {tm['CONSTRAINT']:7.0f} {r['sensor_us']:7.0f} "
                  f"{rest:6.0f} {r['pen_startup_mm']:8.2f}m {r['pen_steady_mm']:9.2f}m {str(r['diverged']):>8s}")
        ratio = results["after"]["wall_s_per_sim_s"] / results["before"]["wall_s_per_sim_s"]
        print(f"after / before compute per simulated second: {ratio:.2f}")


if __name__ == "__main__":
    main()
