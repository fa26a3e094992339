"""Would a larger full-mode cap decide the contact-impulse claim?  The potential study's impulse runs on
finer |dphi| grids, and the claim's R^2 (and its attenuation-corrected value) on each.

    python explorations/impulse_cap.py [--refine 3] [--phases 1] [--store DIR] [--out results/impulse_cap.json]

The full cap runs the impulse design (:func:`undulate.studies._analysis.impulse_design`, 37 dphi x 8 common
phases) refined by 2: 73 dphi over [-pi, pi], 37 distinct |dphi| (+-dphi are mirror images,
:func:`undulate.studies._analysis.by_abs_dphi`).  There the claim's R^2 was 0.82 [0.73, 0.95] and its
runs-needed estimate about 93 |dphi|, assuming the value stays where it is.  This script runs the design
refined by ``2 * refine`` (default 6: 217 dphi, 109 |dphi|, step pi/108; the cap's grid is every third
value, bitwise), the same runs the study makes (``impulse_sweep``, seed 0, resumable in ``--store``), and
prints, on each nested grid, the R^2 of the line on |dphi| with its bootstrap interval at the full cap's
level (97.5 %: the fourth of four looks), the slope, and the R^2 with the common phases' scatter taken out
(:func:`undulate.studies.potential.impulse_r2_without_phase_scatter`).  ``--phases k`` runs k times the
common phases (every one of the study's 8 among them, bitwise): with enough of them each |dphi|'s mean is
nearly exact, which tests the correction for the phases' scatter.  It measures; nothing is asserted.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--refine", type=int, default=3, help="the cap's grid (73 dphi) refined by this (default 3)")
    ap.add_argument("--phases", type=int, default=1, help="the study's 8 common phases refined by this (default 1)")
    ap.add_argument("--store", type=Path, default=Path("impulse-cap-store"), help="the runs' store (resumable)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None, help="write the table as JSON here")
    args = ap.parse_args()
    if args.refine < 1 or args.phases < 1:
        raise SystemExit("--refine and --phases must be >= 1")

    from undulate import stats
    from undulate.provenance import provenance
    from undulate.studies import _analysis as C
    from undulate.studies._shared import impulse_sweep
    from undulate.studies.potential import impulse_r2_without_phase_scatter
    from undulate.sweep import run_sweep

    dphi, phi0 = C.impulse_design(False)
    k = 2 * args.refine
    grid = C.refined(dphi, k)
    phi0 = C.refined(np.append(phi0, 2 * np.pi), args.phases)[:-1]  # the study's phases among them, bitwise
    t0 = time.time()
    res = run_sweep(*impulse_sweep(grid, phi0, 0), args.store, workers=args.workers)
    wall = time.time() - t0
    physics = float(res.timing.get("physics_s", float("nan"))) if res.timing else float("nan")
    imp = res.dataset.isel(replicate=0)["impulse_2T_Ns"].values
    level = stats.look_levels(4)[-1]
    rows = []
    for stride, name in ((k, "the third full look (37 dphi)"), (k // 2, "the full cap (73 dphi)"),
                         (1, f"refined by {args.refine} ({grid.size} dphi)")):
        u, pooled = C.by_abs_dphi(grid[::stride], imp[::stride])
        with stats.at_level(level):
            fit = stats.line_fit(u, np.nanmean(pooled, axis=1))
            clean = impulse_r2_without_phase_scatter(grid[::stride], imp[::stride])
        rows.append({"grid": name, "n_phi0": int(phi0.size), "n_dphi": int(grid[::stride].size),
                     "n_abs_dphi": int(u.size),
                     "runs": int(grid[::stride].size * phi0.size), "r2": fit.r2.to_dict(),
                     "slope_Ns_per_rad": fit.slope.to_dict(), "r2_without_phase_scatter": clean.to_dict()})
        print(f"{name} x {phi0.size} phi0: {u.size} |dphi|, R^2 {fit.r2:.3f}, slope {fit.slope:.3g} N s/rad, "
              f"without the phases' "
              f"scatter {clean:.3f} ({stats.interval_note(level)})")
    print(f"{res.n_computed} runs computed, {res.n_reused} reused, {wall:.0f} s wall on {args.workers} workers, "
          f"physics {physics:.0f} core-s")
    if args.out:
        args.out.write_text(json.dumps({"level": level, "rows": rows, "runs_computed": res.n_computed,
                                        "wall_s": wall, "workers": args.workers, "physics_core_s": physics,
                                        "provenance": provenance()}, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
