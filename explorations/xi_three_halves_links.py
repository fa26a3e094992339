"""Evidence for the xi = 3/2 claim (measured, never asserted): do pairs follow the compatibility
line once the body carries a travelling wave at xi = 3/2?

    python explorations/xi_three_halves_links.py [--duration 60] [--workers 2]

With N = 3 links the two joints of a xi = 3/2 gait move in exact antiphase (a standing wave;
tests/test_wave_symmetry.py), so there is no wave phase for a neighbour to match.  This runs the
paper's pair (d = 0.13 m, default gait and servo, joint amplitude 45 degrees at every N) at
xi = 3/2 for N = 3, 4, 6, 8 and dphi = k pi / 4 (k = -3..3), and prints the final dx / lambda
(mean of the last 3 periods) against the compatibility line dphi / 2 pi, with the RMS distance to
the nearest compatible branch and the least-squares slope through the origin.
"""

from __future__ import annotations

import argparse
import math
from concurrent.futures import ProcessPoolExecutor

import numpy as np


def run(args):
    n, dphi, duration = args
    from undulate import Channel, Gait, Scene, SimOptions, SwimmerGeometry, simulate
    from undulate.observables import neighbour_offsets

    sc = Scene(phases_rad=(0.0, dphi), gait=Gait(waves_per_body=1.5), geometry=SwimmerGeometry(n_links=n),
               channel=Channel(width_m=0.13))
    ds = simulate(sc, SimOptions(duration_s=duration, record=("x", "y")))
    off = neighbour_offsets(ds)
    t = ds["time"].values
    last = t >= t[-1] - 3 * sc.gait.period_s
    return n, dphi, float(off["dx"].values[last, 0].mean()) / sc.wavelength_m


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args()
    links = (3, 4, 6, 8)
    dphis = [k * math.pi / 4 for k in range(-3, 4)]
    with ProcessPoolExecutor(a.workers) as ex:
        res = list(ex.map(run, [(n, d, a.duration) for n in links for d in dphis]))
    print(f"xi = 3/2, d = 0.13 m, {a.duration:g} s; compatibility dx/lambda = dphi/2pi: "
          + " ".join(f"{d / (2 * math.pi):+.3f}" for d in dphis))
    for n in links:
        x = np.array([r[2] for r in res if r[0] == n])
        line = np.array(dphis) / (2 * math.pi)
        resid = x - line - np.round(x - line)
        slope = float((x * line).sum() / (line * line).sum())
        print(f"N = {n}: dx/lambda " + " ".join(f"{v:+.3f}" for v in x)
              + f"   slope {slope:.2f}, RMS residual {math.sqrt(float(np.mean(resid ** 2))):.3f} lambda")


if __name__ == "__main__":
    main()
