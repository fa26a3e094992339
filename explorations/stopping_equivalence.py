"""Runs that stop when decided give the same results as full-length runs: each affected study's
grid run both ways.

For every study whose runners take a stopping rule (pairs, links, groups, basins, confinement,
swimming, sensitivity: ``studies._runners.PAIR_STOP``; packing: ``studies.packing.PACKING_STOP``;
synchronization-pairs and -groups: ``studies.synchronization.PAIR_SYNC_STOP`` / ``GROUP_SYNC_STOP``;
potential's force runs:
``studies.potential.FORCE_STOP``) the study is
run twice through the ordinary machinery (``run_study``, sweeps and all) into two fresh folders:
once with the rule set to None in the study's module (every run full length) and once as shipped.
Per study it prints and writes (``--json``, ``--markdown``):

* the largest |difference| of every steady-offset variable (``dx_*steady*`` / ``dx_final*``, in
  wavelengths) against the steady rule's tolerance (0.01); for closed-loop pairs, of the final
  phase difference (rad, wrapped; lock tolerance 0.15), the time to lock (s) and the final force (N);
* the summary's thresholds (and their intervals) both ways;
* every claim's verdict both ways;
* wall time and physics time (inside ``mujoco.rollout``) both ways, and the runs stopped early.

Timings mean something only on an otherwise idle machine (the load average is printed).

    python explorations/stopping_equivalence.py                          # quick grids
    python explorations/stopping_equivalence.py --only pairs,packing --json /tmp/eq.json
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

STUDIES = ("swimming", "pairs", "confinement", "links", "basins", "groups", "packing", "sensitivity",
           "synchronization-pairs", "potential", "synchronization-groups")
TOL = 0.01


def _rule_names(study: str) -> list[tuple[str, str]]:
    """(module, name) of every binding of the study's stopping rule."""
    if study == "packing":
        return [("packing", "PACKING_STOP")]
    if study == "synchronization-pairs":
        return [("synchronization", "PAIR_SYNC_STOP")]
    if study == "synchronization-groups":
        return [("synchronization", "GROUP_SYNC_STOP")]
    if study == "potential":
        return [("potential", "FORCE_STOP")]
    if study in ("groups", "sensitivity"):  # the groups sweeps are defined in _shared
        return [(study, "PAIR_STOP")] * (study == "sensitivity") + [("_shared", "PAIR_STOP")]
    return [(study, "PAIR_STOP")]


def _run(study: str, out: Path, stopped: bool, quick: bool, workers: int | None) -> tuple:
    import xarray as xr

    from undulate.studies import run_study

    bindings = [(importlib.import_module(f"undulate.studies.{m}"), n) for m, n in _rule_names(study)]
    shipped = [getattr(mod, n) for mod, n in bindings]
    for mod, n in bindings:
        if not stopped:
            setattr(mod, n, None)
    try:
        t0 = time.perf_counter()
        path = run_study(study, out, quick=quick, progress=False, workers=workers)
        wall = time.perf_counter() - t0
    finally:
        for (mod, n), rule in zip(bindings, shipped):
            setattr(mod, n, rule)
    doc = json.loads(path.with_suffix(".json").read_text())
    with xr.open_dataset(path) as ds:
        ds = ds.load()
    return ds, doc, wall


def _offsets(a, b) -> dict[str, float]:
    """Largest |full - stopped| of the dimensionless steady offsets (in wavelengths) and, for packing,
    of the mean joint errors (rad; the heatmap's runs stop too)."""
    out = {}
    for v in a.data_vars:
        offset = "dx" in v and ("steady" in v or "final" in v) and "lambda" in v
        if (offset or v in ("mean_joint_error", "heatmap_joint_error")) and "time" not in a[v].dims and v in b:
            d = np.abs(np.asarray(a[v].values, float) - np.asarray(b[v].values, float))
            out[v] = float(np.nanmax(d)) if np.isfinite(d).any() else float("nan")
        elif v in ("dx", "dx0", "stiffness", "fit_r2") and v in b:  # potential: the force runs' response and fits
            d = np.abs(np.asarray(a[v].values, float) - np.asarray(b[v].values, float))
            out[v] = float(np.nanmax(d)) if np.isfinite(d).any() else float("nan")
            if v == "stiffness":
                out["stiffness (relative)"] = float(np.nanmax(d / np.abs(np.asarray(a[v].values, float))))
        elif v == "broken" and v in b:
            out["broken (runs differing)"] = int((a[v].values != b[v].values).sum())
        elif v in ("R_final", "compat_rms", "max_drift", "dx_final", "frequency") and v in b:  # closed-loop groups
            d = np.abs(np.asarray(a[v].values, float) - np.asarray(b[v].values, float))
            out[v] = float(np.nanmax(d)) if np.isfinite(d).any() else float("nan")
        elif v == "phase_locked" and v in b:
            out["phase_locked (runs differing)"] = int((a[v].values != b[v].values).sum())
        elif v in ("dphi_final", "lock_time", "force_end") and v in b:  # closed-loop pairs
            d = np.asarray(a[v].values, float) - np.asarray(b[v].values, float)
            d = np.abs(np.angle(np.exp(1j * d))) if v == "dphi_final" else np.abs(d)
            out[v] = float(np.nanmax(d)) if np.isfinite(d).any() else float("nan")
            if v == "lock_time":
                out["lock_time (NaN differing)"] = int((np.isnan(a[v].values) != np.isnan(b[v].values)).sum())
                if np.isfinite(d).any():  # the run with the largest difference: full vs stopped lock time
                    k = np.unravel_index(int(np.nanargmax(d)), d.shape)
                    out["lock_time worst (full, stopped)"] = [float(a[v].values[k]), float(b[v].values[k])]
        elif "steady" in v and a[v].dtype == bool and v in b:  # the steady flags: how many differ
            out[f"{v} (flags differing)"] = int((a[v].values != b[v].values).sum())
    return out


def _thresholds(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if "threshold" in k and not k.endswith("_std")}


def _stopped_runs(ds) -> str:
    if "runs_stopped_early" in ds.attrs:
        return f"{ds.attrs['runs_stopped_early']} stopped, {ds.attrs['bracket_reruns']} bracket re-run rounds"
    return ""


def compare(study: str, root: Path, quick: bool, workers: int | None) -> dict:
    full, dfull, wfull = _run(study, root / "full" / study, False, quick, workers)
    stop, dstop, wstop = _run(study, root / "stopped" / study, True, quick, workers)
    verdicts = [(c.get("claim", "?"), c.get("verdict"), s.get("verdict"))
                for c, s in zip(dfull["claims"], dstop["claims"])]
    return {
        "study": study,
        "offsets_max_abs_over_lambda": _offsets(full, stop),
        "thresholds_full": _thresholds(dfull["summary"]),
        "thresholds_stopped": _thresholds(dstop["summary"]),
        "verdicts": verdicts,
        "verdicts_same": all(a == b for _, a, b in verdicts),
        "wall_s": [wfull, wstop],
        "physics_s": [dfull["timing"]["physics_s"], dstop["timing"]["physics_s"]],
        "runs_computed": [dfull["timing"]["n_runs_computed"], dstop["timing"]["n_runs_computed"]],
        "packing": _stopped_runs(stop),
    }


def _markdown(rows: list[dict]) -> str:
    lines = ["| study | max abs offset diff / lambda (tol 0.01) | claims (full -> stopped) | wall s full / stopped "
             "| physics s full / stopped |", "|---|---|---|---|---|"]
    for r in rows:
        off = ", ".join(f"{k} {v:.2g}" if isinstance(v, (int, float)) else f"{k} {v}"
                        for k, v in r["offsets_max_abs_over_lambda"].items()) or "-"
        ver = "; ".join(f"{a} -> {b}" for _, a, b in r["verdicts"])
        lines.append(f"| {r['study']} | {off} | {ver} | {r['wall_s'][0]:.0f} / {r['wall_s'][1]:.0f} | "
                     f"{r['physics_s'][0]:.0f} / {r['physics_s'][1]:.0f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="the full grids (long)")
    ap.add_argument("--only", default=",".join(STUDIES))
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--markdown", type=Path, default=None)
    args = ap.parse_args()
    print(f"load average {os.getloadavg()}", flush=True)
    rows = []
    with tempfile.TemporaryDirectory(prefix="undulate-stop-") as tmp:
        for study in [s.strip() for s in args.only.split(",") if s.strip()]:
            r = compare(study, Path(tmp), not args.full, args.workers)
            rows.append(r)
            print(json.dumps(r, default=str), flush=True)
            if args.json:
                args.json.write_text(json.dumps(rows, indent=1, default=str))
            if args.markdown:
                args.markdown.write_text(_markdown(rows))
    print(_markdown(rows))
    print(f"load average {os.getloadavg()}", flush=True)


if __name__ == "__main__":
    main()
