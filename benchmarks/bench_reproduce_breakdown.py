"""Where a reproduction's time goes: per study, physics (MuJoCo stepping) against everything else.

Runs ``undulate.reproduce`` (quick by default, ``--full`` for the paper's
resolution) into a fresh folder, in this process, and prints a table per
study.  Studies run side by side (``undulate.reproduce.SIDE_BY_SIDE`` at a
time, sharing the worker processes), so their wall times overlap:

* ``wall``: the study's wall time (s), from ``reproduce``'s status;
* ``runs``: simulations it computed (sweep runs, free swimmers included);
* ``physics``: core-seconds inside ``mujoco.rollout``, measured where it
  happens -- each sweep run records its own rollout seconds and steps
  (``undulate._walltime.meter`` around the run, saved in the run file and
  reported back to the parent), and this process counts its own (serial
  sweeps, direct simulations);
* ``us/step``: physics seconds per scene-step;
* ``in runs``: the rest of the runs' own time (model building, control
  generation, recording, writing the run file), core-seconds;
* ``study thread CPU``: CPU seconds of the thread that ran the study in this
  process (its serial runs, merges, summaries with their bootstraps, judging,
  the figure's drawing; not the writing of its files).

The total row gives the whole run's wall time, the CPU time of this process
and its worker processes (``getrusage``), and the core-seconds the cores sat
idle (``wall x cores - CPU``).  With ``--markdown FILE`` the table is also
written as Markdown (for ``docs/performance.md``).  Timings are printed, never
asserted; they mean something only on an otherwise idle machine (the load
average is printed).

    python benchmarks/bench_reproduce_breakdown.py                      # quick, every core
    python benchmarks/bench_reproduce_breakdown.py --full --workers 2
    python benchmarks/bench_reproduce_breakdown.py --only packing,pairs --markdown /tmp/t.md
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import tempfile
import time
from pathlib import Path


def _rows(out: Path, statuses: list[dict]) -> list[dict]:
    rows = []
    for st in statuses:
        doc = json.loads((out / f"{st['name']}.json").read_text()) if st["ok"] else {}
        tm = doc.get("timing", {})
        sweeps = doc.get("sweeps", [])
        in_process_runs = sum(s["timing"].get("runs_wall_s", 0.0) for s in sweeps
                              if s.get("timing", {}).get("executor") == "serial")
        runs_wall = tm.get("runs_in_workers_wall_s", 0.0) + in_process_runs
        phys = float(tm.get("physics_s", 0.0))
        steps = int(tm.get("steps", 0))
        rows.append({"study": st["name"], "wall_s": float(st["wall_s"] or 0.0),
                     "runs": int(tm.get("n_runs_computed", 0)), "physics_s": phys, "steps": steps,
                     "us_per_step": 1e6 * phys / steps if steps else float("nan"),
                     "in_runs_s": max(0.0, runs_wall - phys), "thread_cpu_s": float(tm.get("thread_cpu_s", 0.0))})
    return rows


def _table(rows: list[dict], total: dict) -> str:
    head = ("| study | wall s | runs | physics core-s | µs/step | in runs core-s | study thread CPU s |\n"
            "|---|---:|---:|---:|---:|---:|---:|\n")

    def line(r):
        return (f"| {r['study']} | {r['wall_s']:.1f} | {r['runs']} | {r['physics_s']:.1f} | {r['us_per_step']:.1f} "
                f"| {r['in_runs_s']:.1f} | {r['thread_cpu_s']:.1f} |")
    return head + "\n".join(line(r) for r in rows + [total]) + "\n"


def _reference_us_per_step(n_steps: int = 5000, repeats: int = 3) -> float:
    """This machine's speed now: CPU microseconds per ``mj_step`` of a fixed scene (four default
    swimmers in the 0.22 m channel, their joints driven by a sine), one process, the median of
    ``repeats``.  Printed before and after the run: a shared machine steps the same scene faster at
    some times than at others, and the reproduction's wall time moves with it."""
    import mujoco
    import numpy as np

    from undulate import scene as S
    from undulate.params import Channel, Scene

    model = S.build(Scene(phases_rad=tuple(np.linspace(0.0, 1.5, 4)), channel=Channel(width_m=0.22))).model
    out = []
    for _ in range(repeats):
        data = mujoco.MjData(model)
        t0 = time.process_time()
        for i in range(n_steps):
            data.ctrl[:] = 0.5 * np.sin(0.01 * i + np.arange(model.nu))
            mujoco.mj_step(model, data)
        out.append(1e6 * (time.process_time() - t0) / n_steps)
    return float(np.median(out))


def _cpu() -> float:
    """CPU seconds of this process and its reaped children so far."""
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--full", action="store_true", help="the paper's resolution (default: quick)")
    ap.add_argument("--workers", type=int, default=None, help="local worker processes (default: every core)")
    ap.add_argument("--only", default=None, help="comma-separated studies (default: all)")
    ap.add_argument("--out", type=Path, default=None, help="reproduction folder (default: a fresh temporary one)")
    ap.add_argument("--markdown", type=Path, default=None, help="also write the table to this Markdown file")
    args = ap.parse_args()

    from undulate.reproduce import reproduce
    from undulate.sweep._executors import default_workers
    from undulate import _walltime

    workers = args.workers or default_workers()
    tmp = None
    out = args.out
    if out is None:
        tmp = tempfile.TemporaryDirectory(prefix="undulate-breakdown-")
        out = Path(tmp.name)
    print(f"load average before: {os.getloadavg()}", flush=True)
    ref_before = _reference_us_per_step()
    print(f"reference step (4 swimmers, one process) before: {ref_before:.1f} us", flush=True)
    cpu0 = _cpu()
    t0 = time.perf_counter()
    kw = {"workers": args.workers} if args.workers else {}
    with _walltime.meter() as here:  # everything simulated here and in the workers' reports
        _, statuses = reproduce(out, quick=not args.full, studies=args.only.split(",") if args.only else None,
                                log=lambda m: print(m, flush=True), **kw)
    wall = time.perf_counter() - t0
    cpu = _cpu() - cpu0  # the worker processes are reaped when reproduce returns
    rows = _rows(out, statuses)
    in_proc_studies = sum(r["physics_s"] for r in rows) - sum(
        json.loads((out / f"{s['name']}.json").read_text()).get("timing", {}).get("physics_in_workers_s", 0.0)
        for s in statuses if s["ok"])
    anim_phys = max(0.0, here.seconds - in_proc_studies)  # the animations' (drawn here or in the pool)
    rows.append({"study": "animations", "wall_s": float("nan"), "runs": len(__import__(
        "undulate.reproduce", fromlist=["ANIMATIONS"]).ANIMATIONS), "physics_s": anim_phys, "steps": 0,
        "us_per_step": float("nan"), "in_runs_s": 0.0, "thread_cpu_s": float("nan")})
    steps = sum(r["steps"] for r in rows)
    phys = sum(r["physics_s"] for r in rows)
    cores = os.cpu_count() or 1
    total = {"study": f"**total** (CPU {cpu:.0f} core-s; idle {max(0.0, wall * cores - cpu):.0f} core-s)",
             "wall_s": wall, "runs": sum(r["runs"] for r in rows), "physics_s": phys, "steps": steps,
             "us_per_step": 1e6 * sum(r["physics_s"] for r in rows[:-1]) / steps if steps else float("nan"),
             "in_runs_s": sum(r["in_runs_s"] for r in rows),
             "thread_cpu_s": sum(r["thread_cpu_s"] for r in rows[:-1])}
    mode = "full" if args.full else "quick"
    title = (f"`undulate reproduce --{mode}`, {workers} worker(s), {cores} cores: "
             f"{wall:.0f} s end to end; CPU {cpu:.0f} core-s of {wall * cores:.0f} "
             f"({100 * cpu / (wall * cores):.0f} % busy), physics {phys:.0f} core-s ({100 * phys / max(cpu, 1e-9):.0f} % of the CPU)")
    title += f"; reference step {ref_before:.1f} us before the run (4 swimmers, one process)"
    text = title + "\n\n" + _table(rows, total)
    print("\n" + text, flush=True)
    print(f"load average after: {os.getloadavg()}", flush=True)
    print(f"reference step (4 swimmers, one process) before / after: {ref_before:.1f} / {_reference_us_per_step():.1f} us",
          flush=True)
    failed = [s["name"] for s in statuses if not s["ok"]]
    if failed:
        print(f"FAILED studies: {failed}")
    if args.markdown:
        args.markdown.write_text(text)
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
