"""How much linear drag do swimming pairs need to follow the compatibility line?  The swimming
explanation's demonstration at several drags, on the sensitivity study's full pair phases or finer.

    python explorations/swimming_drag.py [--refine 2] [--drags 0.1 0.5 1 2] [--store DIR] [--out FILE.json]

The sensitivity study explains the failing claim "swimming pairs behave like non-swimming ones" by the
swimming ground's weak linear drag (0.1 N s/m per link), and shows it when the pairs criterion holds with
only the drag raised to 0.5 N s/m.  On its full cap of 33 dphi (2026-11-29) that check stayed undecided:
RMS residual 0.105 [0.048, 0.208] lambda, one pair near pi sliding a body length into single file.  This
script runs the same pairs (``pair_point`` on the swimming ground, 30 s, :data:`PAIR_STOP`, seed 0;
resumable in ``--store``) at each linear drag over the 33 dphi refined by ``refine`` (default 2: 65,
step pi/32; the 33 bitwise every second), and prints per drag the pairs criterion's slope and RMS
residual (95 %, +dphi and -dphi resampled together, as the studies do), the pairs that end in single
file (steady |dy| below a body width), the largest |residual| and the pairs' mean speed.  It measures;
nothing is asserted, and no default depends on it.
"""

from __future__ import annotations

import argparse
import functools
import json
import time
from pathlib import Path

import numpy as np


def _rows(sweep, dphis) -> dict:
    """Per dphi: final dx / lambda, residual / lambda, steady, |dy| and speed (NaN where a run failed)."""
    from undulate import theory

    out = {k: np.full(len(dphis), np.nan) for k in ("dx", "residual", "steady", "dy", "speed")}
    for j, d in enumerate(dphis):
        run = sweep.isel(point=j, replicate=0)
        if bool(run["run_failed"]):
            continue
        v = float(run["dx_final_over_lambda"])
        out["dx"][j], out["residual"][j] = v, float(theory.compatibility_residual(v, d, 1.0))
        out["steady"][j], out["dy"][j] = float(run["steady"]), abs(float(run["dy_final_m"]))
        out["speed"][j] = float(run["speed_m_s"])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--refine", type=int, default=2, help="the 33 dphi refined by this (default 2: 65)")
    ap.add_argument("--drags", type=float, nargs="+", default=[0.1, 0.5, 1.0, 2.0],
                    help="linear drags per link, N s/m (default 0.1 0.5 1 2)")
    ap.add_argument("--store", type=Path, default=Path("swimming-drag-store"), help="the runs' folder (resumable)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None, help="write the table as JSON here")
    args = ap.parse_args()
    if args.refine < 1 or any(not c > 0 for c in args.drags):
        raise SystemExit("--refine must be >= 1 and every --drags value > 0")

    from undulate import stats, studies
    from undulate.params import SwimmerGeometry
    from undulate.provenance import provenance
    from undulate.studies import _analysis as C
    from undulate.studies._runners import PAIR_STOP, pair_point
    from undulate.studies._sensitivity_design import DEFAULT_S
    from undulate.sweep import Grid

    dphis = C.refined(C.refined(C.phase_grid(17), 2), args.refine)  # the sensitivity study's 33, refined
    width = SwimmerGeometry().width_m
    ctx = studies.StudyContext(studies.StudyConfig(out_dir=args.store, quick=False, seed=0, workers=args.workers),
                               "sensitivity", progress=False)
    fn = functools.partial(pair_point, duration_s=DEFAULT_S, stop=PAIR_STOP)
    table, t0 = [], time.time()
    for c in args.drags:
        grid = Grid(points=[{"ground": "swimming", "swim_drag_N_s_per_m": float(c), "dphi_rad": float(d)}
                            for d in dphis], seed=0)
        r = _rows(ctx.sweep(f"swimming-drag-{c:g}", fn, grid), dphis)
        fit, rms = C.compatibility_fit(r["dx"], dphis), C.rms(r["residual"], dphis)
        single = (r["steady"] == 1.0) & (r["dy"] < width)
        worst = int(np.nanargmax(np.abs(r["residual"])))
        row = {"drag_N_s_per_m": c, "n_dphi": int(dphis.size), "slope": fit.slope.to_dict(), "rms_residual_over_lambda":
               rms.to_dict(), "n_single_file": int(single.sum()),
               "single_file_dphi_over_pi": [round(float(d / np.pi), 4) for d in dphis[single]],
               "max_abs_residual_over_lambda": float(np.abs(r["residual"][worst])),
               "max_at_dphi_over_pi": float(dphis[worst] / np.pi), "n_steady": int(np.nansum(r["steady"])),
               "mean_speed_m_s": float(np.nanmean(r["speed"]))}
        table.append(row)
        print(f"drag {c:g} N s/m, {dphis.size} dphi: slope {fit.slope:.3f}, RMS residual {rms:.3f} lambda; "
              f"{row['n_single_file']} in single file {row['single_file_dphi_over_pi']} (x pi); largest |residual| "
              f"{row['max_abs_residual_over_lambda']:.2f} at {row['max_at_dphi_over_pi']:+.3f} pi; "
              f"{row['n_steady']} steady; speed {row['mean_speed_m_s'] * 1e3:.1f} mm/s "
              f"({stats.interval_note(rms.level)})", flush=True)
    wall = time.time() - t0
    print(f"{len(args.drags)} drags x {dphis.size} dphi: {wall:.0f} s wall on {args.workers} workers")
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps({"rows": table, "wall_s": wall, "provenance": provenance()}, indent=1))


if __name__ == "__main__":
    main()
