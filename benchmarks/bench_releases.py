"""Per-step cost of today's model under other MuJoCo releases (measured, never asserted).

    python benchmarks/bench_releases.py --release 3.17.0=/path/a --release 3.12.0=/tmp/mj/3.12.0 [--rounds 3]

Each ``NAME=DIR`` is a folder holding a ``mujoco`` package (``pip install --no-deps --target DIR
mujoco==X``; an empty DIR means the installed one).  For each release, in a fresh subprocess with DIR
first on ``sys.path``, the package compiles two scenes of today's model and rolls each out in one
``mujoco.rollout`` call on one core:

* ``pack``: the packing study's jammed pack, 50 three-link swimmers, rho~ = 3, phi_max = pi
  (phases: draw 0 of seed 0), 2 s;
* ``pair``: a contacting pair (dphi = pi/2 in the 0.13 m channel), 10 s.

Reported: compute per simulated second, per step, the deepest interpenetration after 1 s (the
physics must be the same: within 1 mm, no divergence), and whether the release compiles the model
at all.  Releases are alternated round by round, so drift of the machine falls on all of them.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys

CHILD = r"""
import json, math, sys, time
sys.path.insert(0, sys.argv[1]) if sys.argv[1] else None
import mujoco, numpy as np
from mujoco import rollout
from undulate import Channel, Scene, SimOptions, SwimmerGeometry
from undulate.simulation import compile_scene, resolve_options, _initial_state

def scene(kind):
    if kind == "pair":
        return Scene(phases_rad=(0.0, math.pi / 2), channel=Channel(width_m=0.13)), 10.0
    n, amp, rho, phi = 50, 0.05247, 3.0, math.pi
    u = np.random.default_rng([0, 0]).random(n)
    geo = SwimmerGeometry()
    width = 2 * amp * n / rho
    return Scene(phases_rad=tuple(phi * u), channel=Channel(width_m=width, end_walls_m=1.1 * geo.length_m),
                 lateral_gap_m=width / n - geo.width_m), 2.0

out = {"version": mujoco.__version__}
for kind in ("pack", "pair"):
    sc, dur = scene(kind)
    try:
        o = resolve_options(sc, SimOptions(duration_s=dur, record=("penetration",)))
        cs = compile_scene(sc, o)
    except Exception as e:  # the release cannot build today's model
        out[kind] = {"error": f"{type(e).__name__}: {e}"[:200]}
        continue
    m = cs.model
    from undulate.simulation import controls
    n = o.n_steps
    t = np.arange(n) * o.timestep_s
    u = controls(cs, t)[None]
    s0, _ = _initial_state(m)
    d = mujoco.MjData(m)
    t0 = time.perf_counter()
    st, sd = rollout.rollout(m, d, s0[None], u, nstep=n)
    wall = time.perf_counter() - t0
    md = cs.index.sens_mindist
    depth = np.where(sd[0][:, md] > 0, np.maximum(0.0, -sd[0][:, md + 1]), 0.0)
    steady = depth[int(1.0 / o.timestep_s):].max()
    out[kind] = {"s_per_sim_s": wall / dur, "us_per_step": wall / n * 1e6, "steady_penetration_mm": float(steady) * 1e3,
                 "finite": bool(np.isfinite(st).all()), "dt_s": o.timestep_s, "solver": int(m.opt.solver),
                 "jacobian": int(m.opt.jacobian)}
print(json.dumps(out))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--release", action="append", required=True, help="NAME=DIR (DIR may be empty)")
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    rel = [r.split("=", 1) for r in a.release]
    res: dict[str, list] = {name: [] for name, _ in rel}
    for _ in range(a.rounds):
        for name, where in rel:
            p = subprocess.run([sys.executable, "-c", CHILD, where], capture_output=True, text=True,
                               env={**os.environ, "OMP_NUM_THREADS": "1"})
            if p.returncode:
                res[name].append({"error": ((p.stderr.strip().splitlines() or [f"exit {p.returncode}"])[-1])[:200]})
            else:
                res[name].append(json.loads(p.stdout.strip().splitlines()[-1]))
    print(f"os.getloadavg() at the end: {os.getloadavg()}")
    print("| release | pack: s per simulated s (best) | pack µs/step | pack steady penetration mm | "
          "pair: s per simulated s (best) | pair µs/step |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, runs in res.items():
        def best(kind, key):
            v = [r[kind][key] for r in runs if kind in r and key in r[kind] and r[kind].get("finite", True)]
            return min(v) if v else math.nan
        errs = {r.get("error") or r.get("pack", {}).get("error") for r in runs} - {None}
        diverged = any(not r.get("pack", {}).get("finite", True) for r in runs)
        pen = [r["pack"]["steady_penetration_mm"] for r in runs if "steady_penetration_mm" in r.get("pack", {})]
        note = f" ({'; '.join(sorted(errs))})" if errs else (" (pack not finite)" if diverged else "")
        print(f"| {name}{note} | {best('pack', 's_per_sim_s'):.3f} | {best('pack', 'us_per_step'):.1f} | "
              f"{(max(pen) if pen else math.nan):.2f} | {best('pair', 's_per_sim_s'):.3f} | "
              f"{best('pair', 'us_per_step'):.2f} |")


if __name__ == "__main__":
    main()
