"""Packing thresholds: whole grid against bisection, on the measured full grid (no new runs).

    python explorations/packing_bisection_check.py [--csv explorations/results/packing_grid_penetration_5draws.csv]

The CSV holds every run of the full packing grid (13 phi_max x 19 rho~ x 5
draws, 10 s of 50 swimmers at the default model; ``packing_grid_penetration.py``)
with its mean joint error over t >= 2 s and its compute time.  For every
(phi_max, draw) this script finds the threshold twice with the package's own
code: from the whole column (:func:`undulate.studies.packing.density_threshold`,
what the study did before) and by the study's bisection
(:func:`undulate.studies.packing.bisection_probes`) seeded with the full plan's
heatmap runs, reading the runs it asks for from the CSV.  It prints whether
each column's crossing is monotone, the thresholds side by side (mean over
draws per phi_max), and the runs and compute-seconds each design needs.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--csv", type=Path, default=HERE / "results" / "packing_grid_penetration_5draws.csv")
    args = ap.parse_args()

    from undulate.studies import packing
    from undulate.studies._runners import lone_swimmer

    p = packing.plan(quick=False)
    base = float(lone_swimmer({}, 0)["mean_joint_error_rad"])  # the study's lone swimmer (ctx.lone_swimmer)
    phis, rhos = np.asarray(p.phi_max_rad), np.asarray(p.rho_tilde)
    err = np.full((phis.size, rhos.size, p.draws), np.nan)
    cost = np.zeros_like(err)
    bad = np.zeros(err.shape, bool)
    for r in csv.DictReader(args.csv.open()):
        i = int(np.argmin(np.abs(phis - float(r["phi_max_rad"]))))
        j = int(np.argmin(np.abs(rhos - float(r["rho_tilde"]))))
        k = int(r["draw"])
        bad[i, j, k] = r["diverged"] == "True" or not r["mean_joint_error_rad"]
        err[i, j, k] = float(r["mean_joint_error_rad"]) if r["mean_joint_error_rad"] else np.nan
        cost[i, j, k] = float(r["compute_s"])
    excess = err - base - packing.THRESHOLD_RAD
    heat_j = [int(np.argmin(np.abs(rhos - r))) for r in p.heatmap_rho]

    whole = np.full((phis.size, p.draws), np.nan)
    bis = np.full_like(whole, np.nan)
    runs = np.zeros(err.shape, bool)
    monotone = 0
    for i in range(phis.size):
        for k in range(p.draws):
            above = excess[i, :, k] > 0
            first = int(np.argmax(above)) if above.any() else rhos.size
            monotone += bool(above[first:].all())
            whole[i, k] = packing.density_threshold(rhos, excess[i, :, k], bad[i, :, k])[0]
            known = {j: (None if bad[i, j, k] else bool(above[j])) for j in heat_j} if k < p.heatmap_draws else {}
            for j in known:
                runs[i, j, k] = True
            while nxt := packing.bisection_probes(known, rhos.size):
                for j in nxt:
                    known[j] = None if bad[i, j, k] else bool(above[j])
                    runs[i, j, k] = True
            e = np.where(runs[i, :, k], excess[i, :, k], np.nan)
            bis[i, k] = packing.density_threshold(rhos, e, bad[i, :, k] & runs[i, :, k])[0]
    # the heatmap's runs at densities the threshold grid lacks would add to the bisection's
    extra_heat = [r for r in p.heatmap_rho if np.min(np.abs(rhos - r)) > 1e-9]
    print(f"lone swimmer mean joint error {base:.6f} rad; threshold = lone + {packing.THRESHOLD_RAD} rad")
    print(f"columns whose crossing is monotone in rho~: {monotone} of {phis.size * p.draws}")
    same = np.array_equal(np.isnan(whole), np.isnan(bis)) and np.allclose(whole[np.isfinite(whole)],
                                                                            bis[np.isfinite(bis)], rtol=0, atol=0)
    print(f"per-draw thresholds identical (bit for bit): {same}")
    print("\n| phi_max (rad) | whole grid: mean threshold ± sd | bisection: mean threshold ± sd |\n|---:|---:|---:|")
    for i, ph in enumerate(phis):
        def fmt(t):
            t = t[np.isfinite(t)]
            return f"{t.mean():.4f} ± {t.std(ddof=1):.4f} ({t.size} draws)" if t.size > 1 else \
                (f"{t.mean():.4f} (1 draw)" if t.size else "above the grid")
        print(f"| {ph:.3f} | {fmt(whole[i])} | {fmt(bis[i])} |")
    print(f"\nruns: whole grid {err.size}, bisection + heatmap {int(runs.sum())} "
          f"({runs.sum() / err.size:.0%}){'; heatmap-only densities: ' + str(extra_heat) if extra_heat else ''}")
    print(f"compute-seconds (as measured in the CSV): whole grid {cost.sum():.0f}, bisection + heatmap "
          f"{cost[runs].sum():.0f} ({cost[runs].sum() / cost.sum():.0%})")


if __name__ == "__main__":
    main()
