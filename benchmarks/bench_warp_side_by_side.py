"""Do Warp models stepping side by side overlap on a GPU?  (Measured, never asserted.)

    python benchmarks/bench_warp_side_by_side.py [--device cuda] [--models 1,2,4,8,16] [--worlds 18]
                                                  [--steps 320] [--repeat 3]

Why: on the H200 (2026-11-27, e9b2b39) a quick reproduction on the Warp backend stepped ~20 small
Warp models at once (every study side by side, each model on its own stream), and an 18-world pair
sweep of at most 45 000 steps was at 84 % of its simulated time after 103 s: ~2.7 ms a step, ~8x
what one model's step costs alone (the same lease's pair run, one world alone: 0.32 ms a step end
to end; 0.34 ms at 1 024 worlds on the device, the first H200 check).  So the models' steps overlapped little, if at all.  This separates where they queue:

* ``device`` -- K models of the default pair (``--worlds`` worlds each), each stepped by its own
  thread on its own stream with its captured graphs only (``--steps`` steps, then a wait for its
  stream): no host work besides the launches.  If the device overlapped the streams, the wall time
  would stay near one model's as K grows.
* ``end_to_end`` -- the same K models through :meth:`WarpRollout.rollout_samples`, as a study's
  sweep steps them (control table up, reduced samples down, the host's NumPy in between): the host
  work of K threads under one interpreter lock added.
* ``merged`` -- the K models' worlds as the worlds of one model (K x ``--worlds``), one thread: what
  gathering concurrent sweeps of one structure into one model would give.

Each figure is the best of ``--repeat`` (the machine may be shared), as milliseconds per step of
the whole set (wall / steps).  The CUDA driver reads ``CUDA_DEVICE_MAX_CONNECTIONS`` (hardware work
queues; 8 by default, 32 at most) when Warp creates its context, so the GPU check runs this script
once with it unset and once with it at 32 (the value is in the output).  The last line,
``json {...}``, is for scripts (the GPU check's ``side-by-side`` step).  On Warp's CPU device
(``--device cpu``, no streams) the models take turns (a check of this script, not a figure).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import threading
import time


def _maker(steps: int, device: str):
    """``make(nw)``: a Warp rollout of ``nw`` worlds of the default pair (reduced on the device) with
    its graphs captured, the state and the controls of ``steps`` steps to step it with."""
    import numpy as np

    from undulate import Scene, SimOptions
    from undulate.simulation import _initial_state, compile_scene, resolve_options
    from undulate.simulation._warp import WarpRollout, _Reduction

    sc = Scene(phases_rad=(0.0, math.pi / 2))
    opts = resolve_options(sc, SimOptions(duration_s=1.0, backend="warp", device=device))
    cs = compile_scene(sc, opts)  # the Warp model is derived from it (no second compile)
    s0, _ = _initial_state(cs.model)
    u1 = cs.controls(np.arange(steps) * opts.timestep_s)
    sps = 10
    ix = cs.index

    def make(nw: int):
        red = _Reduction(sps, ix.sens_pair, ix.sens_wall, ix.sens_mindist, [sc.contact.max_penetration_m] * nw)
        r = WarpRollout([cs] * nw, opts, device, reduce=red)
        cur = np.tile(s0, (nw, 1))
        u = np.ascontiguousarray(np.broadcast_to(u1, (nw, steps, u1.shape[1])))
        r.rollout_samples(cur, u, steps)  # compiled (or loaded), graphs captured
        return r, cur, u

    return make


def _device_steps(r, steps: int) -> None:
    """``steps`` steps of ``r``'s one group from its captured graphs (from row 0 of its control table
    and samples, as a chunk starts), then a wait for its stream."""
    import warp as wp

    from undulate.simulation._warp import _DEVICE_LOCK

    g = r.groups[0]
    zero = wp.zeros(1, dtype=int, device="cpu")
    with wp.ScopedDevice(g.device):
        if g.stream is None:  # Warp's CPU device: one thread at a time, as the backend steps it
            with _DEVICE_LOCK:
                wp.copy(g.k, zero)  # the step counter: the table's and the samples' row
                g._steps(steps)
                g._sync()
            return
        wp.copy(g.k, zero, stream=g.stream)
        g._steps(steps)
        g._sync()


def _together(jobs) -> float:
    """Wall seconds of running every ``job()`` on its own thread, started together."""
    start = threading.Barrier(len(jobs) + 1)
    errors: list = []

    def run(job):
        start.wait()
        try:
            job()
        except BaseException as e:  # noqa: BLE001 - re-raised below
            errors.append(e)

    threads = [threading.Thread(target=run, args=(j,)) for j in jobs]
    for t in threads:
        t.start()
    start.wait()
    t0 = time.perf_counter()
    for t in threads:
        t.join()
    if errors:
        raise errors[0]
    return time.perf_counter() - t0


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--device", default="cuda")
    p.add_argument("--models", default="1,2,4,8,16", help="numbers of models side by side")
    p.add_argument("--worlds", type=int, default=18, help="worlds of each model")
    p.add_argument("--steps", type=int, default=320, help="steps per measurement (a multiple of 10)")
    p.add_argument("--repeat", type=int, default=3)
    a = p.parse_args()
    ks = sorted({int(x) for x in a.models.split(",") if x})
    if not ks or ks[0] < 1 or a.worlds < 1 or a.steps < 10 or a.steps % 10 or a.repeat < 1:
        p.error("--models: positive integers; --worlds >= 1; --steps a positive multiple of 10; --repeat >= 1")
    t0 = time.perf_counter()

    from undulate.simulation._warp import device_name

    make = _maker(a.steps, a.device)
    each = [make(a.worlds) for _ in range(ks[-1])]
    setup_s = time.perf_counter() - t0
    out = {"device": device_name(a.device), "cuda_device_max_connections": os.environ.get("CUDA_DEVICE_MAX_CONNECTIONS"),
           "worlds_each": a.worlds, "steps": a.steps, "setup_s": setup_s, "rows": []}
    for k in ks:
        sub = each[:k]
        dev = min(_together([lambda r=r: _device_steps(r, a.steps) for r, _, _ in sub]) for _ in range(a.repeat))
        e2e = min(_together([lambda r=r, c=c, u=u: r.rollout_samples(c, u, a.steps) for r, c, u in sub])
                  for _ in range(a.repeat))
        if k == 1:
            merged = dev
        else:
            m = make(k * a.worlds)[0]
            merged = min(_together([lambda: _device_steps(m, a.steps)]) for _ in range(a.repeat))
            m.close()
        row = {"models": k, "device_ms_per_step": 1e3 * dev / a.steps, "end_to_end_ms_per_step": 1e3 * e2e / a.steps,
               "merged_device_ms_per_step": 1e3 * merged / a.steps}
        out["rows"].append(row)
        print(f"{k:3d} models x {a.worlds} worlds: device {row['device_ms_per_step']:.3f} ms a step, end to end "
              f"{row['end_to_end_ms_per_step']:.3f}, one model of {k * a.worlds} worlds "
              f"{row['merged_device_ms_per_step']:.3f}", flush=True)
    for r, _, _ in each:
        r.close()
    out["wall_s"] = time.perf_counter() - t0
    print("json " + json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
