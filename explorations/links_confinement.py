"""The link-number trend against the channel width (exploratory; measured, never asserted).

    python explorations/links_confinement.py

Pairs of N = 3, 5, 7, 9 links with the joint amplitude that holds the free
swimmer's body amplitude A at the 3-link value (the sensitivity study's
equal-A rule: beta = 45, 30.9, 22.7, 17.8 degrees), xi = 1, the paper's nine
dphi, 30 s from dx0 = 0, each N at the simulator's time step, in channels of
0.13 m (the pairs' d/2A = 1.24), 0.12 m and 0.115 m (d/2A = 1.10).  Printed
per (d, N): the RMS distance from the nearest compatibility branch (95 %
bootstrap interval), the median lateral spacing of the two centre lines and
the final dx / lambda per dphi.  Results: docs/claims_explained.md (links).
"""

from __future__ import annotations

import math
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from undulate.studies import _analysis as C
from undulate.studies import _sensitivity_runs as SR
from undulate.studies._runners import BODY_LENGTH_M, group_point

BETA_DEG = {3: 45.0, 5: 30.9, 7: 22.7, 9: 17.8}
WIDTHS_M = (0.13, 0.12, 0.115)
A_M = 0.05226  # the free 3-link swimmer's A (the equal-A target)


def one(args):
    n, width, dphi = args
    point = {"n_links": n, "amplitude_rad": math.radians(BETA_DEG[n]), "timestep_s": SR._timestep(n),
             "waves_per_body": 1.0, "dphi_rad": dphi}
    run = group_point(point, 0, n_swimmers=2, channel_width_m=width, duration_s=30.0)
    dx, res, _ = SR._pair_rows(run, dphi, BODY_LENGTH_M, A_M)[C.STEADY_WINDOW]
    dy = float(np.mean(np.abs(run["y"].values[-50:, 1] - run["y"].values[-50:, 0])))
    return dx, res, dy


def main() -> None:
    with ProcessPoolExecutor(2) as ex:
        for width in WIDTHS_M:
            for n in BETA_DEG:
                res = list(ex.map(one, [(n, width, float(d)) for d in C.paper_phases()]))
                rms = C.rms(np.array([r[1] for r in res]))
                print(f"d = {width} m, N = {n}: RMS {rms.value:.3f} [{rms.low:.3f}, {rms.high:.3f}] lambda, "
                      f"spacing {np.median([r[2] for r in res]) * 1e3:.1f} mm; dx/lambda "
                      + " ".join(f"{r[0]:+.3f}" for r in res), flush=True)


if __name__ == "__main__":
    main()
