"""Interpenetration and divergence over the full packing grid (measured, never asserted).

    python explorations/packing_grid_penetration.py [--draws 1] [--first-draw 0] [--workers 2] [--out grid.csv]

Every (phi_max, rho~) point of the full packing study (13 phase spreads x 19
densities, :func:`undulate.studies.packing.plan`), ``--draws`` phase draws each
(draw d uses the study's phases, ``default_rng([0, d])``), 10 s of 50 swimmers
at the default model and time step.  One line per run to ``--out`` (CSV): the
deepest interpenetration during start-up (t < 2 s) and after (t >= 2 s), whether
the run diverged, the mean joint error over t >= 2 s, and the compute time; a
summary at the end.
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np


def one(args) -> dict:
    phi, rho, draw, amp, duration = args
    from undulate import Channel, Scene, SimOptions, simulate
    from undulate.errors import DivergenceError

    n = 50
    width = 2 * amp * n / rho
    u = np.random.default_rng([0, draw]).random(n)
    scene = Scene(phases_rad=tuple(phi * u), channel=Channel(width_m=width, end_walls_m=1.1 * 0.54),
                  lateral_gap_m=width / n - 0.015)
    t0 = time.perf_counter()
    row = dict(phi_max_rad=phi, rho_tilde=rho, draw=draw, diverged=False)
    try:
        import dataclasses

        opt = SimOptions(duration_s=duration, sample_rate_hz=10)
        if any(f.name == "record" for f in dataclasses.fields(SimOptions)):  # only what is measured here
            opt = dataclasses.replace(opt, record=("joint_error", "penetration"))
        ds = simulate(scene, opt)
    except DivergenceError as e:
        row.update(diverged=True, message=str(e)[:120])
    else:
        pen = ds["penetration"]
        row.update(pen_startup_mm=float(pen.sel(time=slice(0, 2 - 1e-9)).max()) * 1e3,
                   pen_steady_mm=float(pen.sel(time=slice(2, None)).max()) * 1e3,
                   mean_joint_error_rad=float(ds["joint_error"].sel(time=slice(2, None)).mean()),
                   timestep_s=float(ds.attrs["timestep"]))
    row["compute_s"] = time.perf_counter() - t0
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=1)
    ap.add_argument("--first-draw", type=int, default=0, help="draws first-draw .. first-draw + draws - 1")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--out", default="packing_grid_penetration.csv")
    args = ap.parse_args()
    from undulate.studies._runners import lone_swimmer
    from undulate.studies.packing import plan

    amp = float(lone_swimmer({}, 0)["amplitude_m"])  # already rounded (studies._runners.round_amplitude)
    p = plan(quick=False)
    jobs = [(phi, rho, d, amp, args.duration) for d in range(args.first_draw, args.first_draw + args.draws) for rho in p.rho_tilde for phi in p.phi_max_rad]
    fields = ["phi_max_rad", "rho_tilde", "draw", "diverged", "pen_startup_mm", "pen_steady_mm",
              "mean_joint_error_rad", "timestep_s", "compute_s", "message"]
    rows = []
    with open(args.out, "w", newline="") as f, ProcessPoolExecutor(args.workers) as ex:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        for i, r in enumerate(ex.map(one, jobs)):
            rows.append(r)
            w.writerow(r)
            f.flush()
            print(f"{i + 1}/{len(jobs)} phi {r['phi_max_rad']:.2f} rho {r['rho_tilde']:.2f}: "
                  f"start {r.get('pen_startup_mm', math.nan):.2f} mm steady {r.get('pen_steady_mm', math.nan):.2f} mm "
                  f"{'DIVERGED ' if r['diverged'] else ''}{r['compute_s']:.1f} s", flush=True)
    ok = [r for r in rows if not r["diverged"]]
    print(f"\n{len(rows)} runs, {len(rows) - len(ok)} diverged; steady > 1 mm: "
          f"{sum(r['pen_steady_mm'] > 1 for r in ok)}; start-up > 2 mm: {sum(r['pen_startup_mm'] > 2 for r in ok)}; "
          f"deepest steady {max(r['pen_steady_mm'] for r in ok):.2f} mm, start-up {max(r['pen_startup_mm'] for r in ok):.2f} mm; "
          f"compute {sum(r['compute_s'] for r in rows):.0f} s")


if __name__ == "__main__":
    main()
