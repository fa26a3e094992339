"""The two channel widths that fix what the paper's confinement ``d`` is (docs/confinement_d.md).

    python explorations/d_thresholds.py [--out explorations/results/d_thresholds.json]
    python explorations/d_thresholds.py --cohesion   # the potential study's force runs by d/2A

The paper says of ``d/2A`` (its section on confinement): below 0.5 "the
undulatory gait is obstructed", above 1 "swimmers through initial contact
can push each other away".  This script finds, in our model, the two
channel widths ``W`` (wall to wall, m) at which a *pair* of default
3-link swimmers crosses those two behaviours, so that the map between
``d/2A`` and ``W`` can be read off them rather than assumed:

* **obstruction** -- an in-phase pair (``dphi = 0``) started straight and
  laterally in contact, from ``dx0 / lambda`` = 0 and +-0.1, for
  :data:`OBSTRUCT_S`: obstructed where its mean joint error (over both
  swimmers and their joints, t >= 2 s, as the lone swimmer's) exceeds the
  lone swimmer's by the packing study's 0.01 rad (the paper's own contact
  criterion, :data:`undulate.studies.packing.THRESHOLD_RAD`);
* **push-apart** -- a pair started side by side (``dx0 = 0``) and laterally
  in contact with ``dphi`` = pi/4, pi/2, 3 pi/4, pi, for :data:`PUSH_S`:
  free where the swimmer-swimmer contact force is exactly zero over the
  last :data:`LATE_PERIODS` periods (the pair has stopped touching).

Each threshold is first scanned on a coarse grid of widths (to show a clean
transition: one change of state along the grid), then bisected on the
width between the coarse grid's last "obstructed"/"touching" width and the
next one to a bracket of at most :data:`BRACKET_M`.  Runs are deterministic,
so the bracket is the whole uncertainty.  ``A`` is the lone swimmer's gait
amplitude as every study measures it (:func:`undulate.studies._runners.lone_swimmer`);
the pair scenes are the studies' (:func:`undulate.studies._runners.pair_scene`:
viscous ground, 15 mm links).  Both thresholds are then written as ``W / 2A``
(``d`` the whole channel) and ``W / (2 * 2A)`` (``d`` the channel per swimmer
side by side).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from undulate import SimOptions
from undulate.provenance import provenance
from undulate.simulation import simulate
from undulate.studies._runners import LONE_SKIP_S, lone_swimmer, pair_scene
from undulate.studies.packing import THRESHOLD_RAD

OBSTRUCT_S = 20.0
"""Length of an in-phase pair's run, s (10 periods; the mean is over t >= 2 s)."""
PUSH_S = 40.0
"""Length of a detuned pair's run, s (20 periods)."""
LATE_PERIODS = 3
"""Periods at the end of a detuned run over which the contact force must be zero."""
BRACKET_M = 0.001
"""Bisection stops when the bracket is at most this wide, m."""
OBSTRUCT_DX0 = (0.0, 0.1, -0.1)
PUSH_DPHI = (math.pi / 4, math.pi / 2, 3 * math.pi / 4, math.pi)
OBSTRUCT_SCAN_M = tuple(np.round(np.arange(0.080, 0.1401, 0.005), 4))
PUSH_SCAN_M = tuple(np.round(np.arange(0.110, 0.3001, 0.010), 4))


def _run(point: dict, duration_s: float):
    return simulate(pair_scene(point), SimOptions(duration_s=duration_s, sample_rate_hz=20.0))


def obstruction_run(width_m: float, dx0_over_lambda: float, lone_err: float) -> dict:
    ds = _run({"channel_width_m": width_m, "dx0_over_lambda": dx0_over_lambda}, OBSTRUCT_S)
    err = float(ds["joint_error"].where(ds["time"] >= LONE_SKIP_S).mean())
    return {"width_m": width_m, "mean_joint_error_rad": err, "excess_rad": err - lone_err,
            "obstructed": bool(err - lone_err > THRESHOLD_RAD)}


def push_run(width_m: float, dphi_rad: float) -> dict:
    ds = _run({"channel_width_m": width_m, "dphi_rad": dphi_rad}, PUSH_S)
    t = ds["time"].values
    late = t >= t[-1] - LATE_PERIODS * float(ds.attrs["period"])
    f = ds["contact_force_pair"].values[:, 0]
    y, x = ds["y"].values, ds["x"].values
    lam = float(ds.attrs["wavelength"])
    return {"width_m": width_m, "late_contact_force_max_N": float(np.abs(f[late]).max()),
            "late_contact_force_mean_N": float(np.abs(f[late]).mean()),
            "late_dy_m": float(np.abs(y[late, 1] - y[late, 0]).mean()),
            "late_dx_over_lambda": float((x[late, 1] - x[late, 0]).mean() / lam),
            "free": bool(np.abs(f[late]).max() == 0.0)}


def threshold(run, scan, bad_key: str) -> dict:
    """Coarse scan, then bisection between the last ``bad`` width and the next one."""
    coarse = [run(w) for w in scan]
    bad = [r[bad_key] for r in coarse]
    changes = int(sum(a != b for a, b in zip(bad, bad[1:])))
    idx = [i for i, b in enumerate(bad) if b]
    if not idx or idx[-1] == len(scan) - 1:
        return {"coarse": coarse, "state_changes_along_scan": changes, "bracket_m": None, "bisection": []}
    lo, hi = float(scan[idx[-1]]), float(scan[idx[-1] + 1])
    steps = []
    while hi - lo > BRACKET_M + 1e-12:
        mid = round((lo + hi) / 2, 6)
        r = run(mid)
        steps.append(r)
        lo, hi = (mid, hi) if r[bad_key] else (lo, mid)
    return {"coarse": coarse, "state_changes_along_scan": changes, "bracket_m": [lo, hi], "bisection": steps}


COHESION_D_OVER_2A = (0.5, 0.6, 0.7, 0.8, 0.9, 1.2)
COHESION_FORCES_N = (0.005, 0.02, 0.1, 0.3)


def cohesion(out_path: str) -> None:
    """``--cohesion``: where a settled in-phase pair holds against the potential study's forces, by d/2A per
    swimmer (its force runs, judged by its own rules: broken when dx / lambda > BREAK or the last 3 period
    means span more than DRIFT)."""
    import functools

    from undulate.studies._runners import pair_point
    from undulate.studies.potential import BREAK, DRIFT, DURATION_S, FORCE_STOP, SETTLE_S, _last_periods
    from undulate.theory import channel_width_m

    t0 = time.process_time()
    amp = float(lone_swimmer({}, 0)["amplitude_m"])
    fn = functools.partial(pair_point, duration_s=DURATION_S, force_onset_s=SETTLE_S, stop=FORCE_STOP)
    rows = []
    for r in COHESION_D_OVER_2A:
        for f in COHESION_FORCES_N:
            g = fn({"amplitude_m": amp, "d_over_2A": r, "force_N": f}, 0)
            pm = g["dx_period_over_lambda"].values[None, :]
            k_before = int(np.flatnonzero(g["period_time"].values < SETTLE_S)[-1])
            last = _last_periods(pm, 3)[0]
            dx, drift = float(last.mean() - pm[0, k_before]), float(np.ptp(last))
            rows.append({"d_over_2A": r, "channel_width_m": float(channel_width_m(r, amp, 2)), "force_N": f,
                         "dx_over_lambda": dx, "drift_over_lambda": drift,
                         "held": bool(dx <= BREAK and drift <= DRIFT)})
            print(f"d/2A = {r:.1f} (W = {rows[-1]['channel_width_m'] * 1e3:.0f} mm), dF = {f} N: dx/lambda {dx:.3f}, "
                  f"drift {drift:.4f}: {'held' if rows[-1]['held'] else 'broken'}", flush=True)
    out = {"what": "in-phase pairs (beta = 45 deg) settled, then pulled apart by dF, by d/2A per swimmer "
                   "(explorations/d_thresholds.py --cohesion; docs/confinement_d.md)",
           "provenance": provenance(), "amplitude_m": amp, "rows": rows,
           "rules": {"break_over_lambda": BREAK, "drift_over_lambda": DRIFT, "settle_s": SETTLE_S,
                     "duration_s": DURATION_S},
           "cpu_s": round(time.process_time() - t0, 1)}
    Path(out_path).write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    print(f"cpu {out['cpu_s']} s -> {out_path}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(Path(__file__).parent / "results" / "d_thresholds.json"))
    ap.add_argument("--cohesion", action="store_true",
                    help="instead: where a settled in-phase pair holds against the potential study's forces "
                         "(writes results/d_cohesion.json)")
    args = ap.parse_args(argv)
    if args.cohesion:
        return cohesion(str(Path(__file__).parent / "results" / "d_cohesion.json"))
    t0 = time.process_time()
    lone = lone_swimmer({}, 0)
    amp, lone_err = float(lone["amplitude_m"]), float(lone["mean_joint_error_rad"])
    two_a = 2 * amp
    print(f"lone swimmer: A = {amp * 1e3:.2f} mm (2A = {two_a * 1e3:.2f} mm), joint error {lone_err:.5f} rad")

    obstruction = {}
    for x0 in OBSTRUCT_DX0:
        r = threshold(lambda w, x0=x0: obstruction_run(w, x0, lone_err), OBSTRUCT_SCAN_M, "obstructed")
        obstruction[f"{x0:+.1f}"] = r
        print(f"obstruction dx0/lambda = {x0:+.1f}: bracket {r['bracket_m']}, "
              f"changes along scan {r['state_changes_along_scan']}; excess (mrad) "
              + " ".join(f"{c['width_m'] * 1e3:.0f}:{c['excess_rad'] * 1e3:.1f}" for c in r["coarse"]))
    push = {}
    for dphi in PUSH_DPHI:
        def run(w, dphi=dphi):
            out = push_run(w, dphi)
            out["touching"] = not out["free"]
            return out
        r = threshold(run, PUSH_SCAN_M, "touching")
        push[f"{dphi:.4f}"] = r
        print(f"push-apart dphi = {dphi:.3f}: bracket {r['bracket_m']}, changes along scan "
              f"{r['state_changes_along_scan']}; late force max (N) "
              + " ".join(f"{c['width_m'] * 1e3:.0f}:{c['late_contact_force_max_N']:.3g}" for c in r["coarse"]))

    def both(bracket):
        if bracket is None:
            return None
        return {"whole_width_d_over_2A": [b / two_a for b in bracket],
                "per_swimmer_d_over_2A": [b / (2 * two_a) for b in bracket]}

    ob_hi = [o["bracket_m"] for o in obstruction.values()]
    pu_hi = [p["bracket_m"] for p in push.values()]
    ob_all = None if any(b is None for b in ob_hi) else [max(b[0] for b in ob_hi), max(b[1] for b in ob_hi)]
    pu_all = None if any(b is None for b in pu_hi) else [max(b[0] for b in pu_hi), max(b[1] for b in pu_hi)]
    out = {
        "what": "channel widths (m) at which a pair of default 3-link swimmers becomes obstructed (in phase) "
                "and pushes itself apart (detuned); explorations/d_thresholds.py, docs/confinement_d.md",
        "provenance": provenance(),
        "cpu_s": None,
        "parameters": {"obstruct_duration_s": OBSTRUCT_S, "push_duration_s": PUSH_S, "late_periods": LATE_PERIODS,
                       "bracket_m": BRACKET_M, "obstruct_dx0_over_lambda": list(OBSTRUCT_DX0),
                       "push_dphi_rad": list(PUSH_DPHI), "obstruct_scan_m": list(OBSTRUCT_SCAN_M),
                       "push_scan_m": list(PUSH_SCAN_M), "joint_error_threshold_rad": THRESHOLD_RAD,
                       "joint_error_skip_s": LONE_SKIP_S, "scene": "undulate.studies._runners.pair_scene defaults "
                       "(3 links, 15 mm wide, viscous ground, beta = 45 deg, xi = 1, f = 0.5 Hz)"},
        "lone": {"amplitude_m": amp, "two_A_m": two_a, "mean_joint_error_rad": lone_err},
        "obstruction": obstruction,
        "push_apart": push,
        "thresholds": {
            "obstruction_bracket_m": ob_all, "obstruction_as_d_over_2A": both(ob_all),
            "push_apart_all_dphi_bracket_m": pu_all, "push_apart_as_d_over_2A": both(pu_all),
            "rule": "obstruction: the widest bracket over the dx0 starts (below its low end some start is "
                    "obstructed); push-apart: the widest bracket over dphi (above its high end every dphi tested "
                    "ends free)"},
    }
    out["cpu_s"] = round(time.process_time() - t0, 1)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    print(json.dumps(out["thresholds"], indent=1))
    print(f"cpu {out['cpu_s']} s -> {args.out}")


if __name__ == "__main__":
    main()
