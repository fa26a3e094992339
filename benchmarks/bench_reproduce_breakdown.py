"""Where a reproduction's time goes: per study, physics (MuJoCo stepping) against everything else.

Runs ``undulate.reproduce`` (quick by default, ``--full`` for the paper's
resolution) into a fresh folder, in this process, and prints a table per
study:

* ``wall``: the study's wall time (s), from ``reproduce``'s status;
* ``runs``: simulations it computed (sweep runs, free swimmers included);
* ``physics``: core-seconds inside ``mujoco.rollout``, measured where it
  happens -- each sweep run records its own rollout seconds and steps
  (``undulate._physics.meter`` around the run, saved in the run file and
  reported back to the parent), and this process counts its own (serial
  sweeps, direct simulations);
* ``us/step``: physics seconds per scene-step;
* ``physics share``: physics core-seconds over the core-seconds the study
  held (``wall x workers``);
* ``in runs``: the rest of the runs' own time (model building, control
  generation, recording, writing the run file), core-seconds;
* ``outside runs``: everything else the study held the cores for (process
  start-up and imports, waiting on the last runs, merging, summary,
  figure, files), ``wall x workers - runs' time``.

The last rows add the animations and the report, and the total.  With
``--markdown FILE`` the table is also written as Markdown (for
``docs/performance.md``).  Timings are printed, never asserted; they mean
something only on an otherwise idle machine (the load average is printed).

    python benchmarks/bench_reproduce_breakdown.py                      # quick, every core
    python benchmarks/bench_reproduce_breakdown.py --full --workers 2
    python benchmarks/bench_reproduce_breakdown.py --only packing,pairs --markdown /tmp/t.md
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path


def _rows(out: Path, statuses: list[dict], workers: int) -> list[dict]:
    rows = []
    for st in statuses:
        doc = json.loads((out / f"{st['name']}.json").read_text()) if st["ok"] else {}
        tm = doc.get("timing", {})
        sweeps = doc.get("sweeps", [])
        in_process_runs = sum(s["timing"].get("runs_wall_s", 0.0) for s in sweeps
                              if s.get("timing", {}).get("executor") == "serial")
        runs_wall = tm.get("runs_in_workers_wall_s", 0.0) + in_process_runs
        wall = float(st["wall_s"] or 0.0)
        phys = float(tm.get("physics_s", 0.0))
        steps = int(tm.get("steps", 0))
        rows.append({"study": st["name"], "wall_s": wall, "runs": int(tm.get("n_runs_computed", 0)),
                     "physics_s": phys, "steps": steps,
                     "us_per_step": 1e6 * phys / steps if steps else float("nan"),
                     "share": phys / (wall * workers) if wall else float("nan"),
                     "in_runs_s": max(0.0, runs_wall - phys),
                     "outside_s": max(0.0, wall * workers - runs_wall)})
    return rows


def _table(rows: list[dict], total: dict, workers: int) -> str:
    head = ("| study | wall s | runs | physics core-s | µs/step | physics share | in runs core-s | "
            "outside runs core-s |\n|---|---:|---:|---:|---:|---:|---:|---:|\n")
    def line(r):
        return (f"| {r['study']} | {r['wall_s']:.1f} | {r['runs']} | {r['physics_s']:.1f} | {r['us_per_step']:.1f} "
                f"| {100 * r['share']:.0f} % | {r['in_runs_s']:.1f} | {r['outside_s']:.1f} |")
    return head + "\n".join(line(r) for r in rows + [total]) + "\n"


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
    from undulate import _physics

    workers = args.workers or default_workers()
    tmp = None
    out = args.out
    if out is None:
        tmp = tempfile.TemporaryDirectory(prefix="undulate-breakdown-")
        out = Path(tmp.name)
    print(f"load average before: {os.getloadavg()}", flush=True)
    t0 = time.perf_counter()
    kw = {"workers": args.workers} if args.workers else {}
    with _physics.meter() as here:  # what this process simulates (serial sweeps, direct runs, animations)
        _, statuses = reproduce(out, quick=not args.full, studies=args.only.split(",") if args.only else None,
                                log=lambda m: print(m, flush=True), **kw)
    wall = time.perf_counter() - t0
    rows = _rows(out, statuses, workers)
    studies_wall = sum(r["wall_s"] for r in rows)
    # animations and the report run in this process after the studies: their physics is this
    # process's rollout time minus what the studies counted in this process
    in_proc_studies = sum(json.loads((out / f"{s['name']}.json").read_text()).get("timing", {}).get("physics_s", 0.0)
                          - json.loads((out / f"{s['name']}.json").read_text()).get("timing", {}).get(
                              "physics_in_workers_s", 0.0) for s in statuses if s["ok"])
    anim_phys = max(0.0, here.seconds - in_proc_studies)
    anim_wall = max(0.0, wall - studies_wall)
    rows.append({"study": "animations + report", "wall_s": anim_wall, "runs": len(__import__(
        "undulate.reproduce", fromlist=["ANIMATIONS"]).ANIMATIONS), "physics_s": anim_phys, "steps": 0,
        "us_per_step": float("nan"), "share": anim_phys / (anim_wall * workers) if anim_wall else float("nan"),
        "in_runs_s": 0.0, "outside_s": max(0.0, anim_wall * workers - anim_phys)})
    steps = sum(r["steps"] for r in rows)
    phys = sum(r["physics_s"] for r in rows)
    total = {"study": "**total**", "wall_s": wall, "runs": sum(r["runs"] for r in rows), "physics_s": phys,
             "steps": steps, "us_per_step": 1e6 * sum(r["physics_s"] for r in rows[:-1]) / steps if steps else float("nan"),
             "share": phys / (wall * workers), "in_runs_s": sum(r["in_runs_s"] for r in rows),
             "outside_s": sum(r["outside_s"] for r in rows)}
    mode = "full" if args.full else "quick"
    title = (f"`undulate reproduce --{mode}`, {workers} worker(s), {os.cpu_count()} cores: "
             f"{wall:.0f} s end to end; physics {phys:.0f} core-s of {wall * workers:.0f} "
             f"({100 * phys / (wall * workers):.0f} %), everything else {100 - 100 * phys / (wall * workers):.0f} %")
    text = title + "\n\n" + _table(rows, total, workers)
    print("\n" + text, flush=True)
    print(f"load average after: {os.getloadavg()}", flush=True)
    failed = [s["name"] for s in statuses if not s["ok"]]
    if failed:
        print(f"FAILED studies: {failed}")
    if args.markdown:
        args.markdown.write_text(text)
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
