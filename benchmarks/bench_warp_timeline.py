"""What a run's Warp models did, from their timeline (``UNDULATE_WARP_TIMELINE``; measured, never asserted).

    python benchmarks/bench_warp_timeline.py TIMELINE.jsonl [--json]

The backend appends every chunk a Warp model steps to the timeline
(:class:`undulate.simulation._warp_timeline.Timeline`).  This reads one run's timeline -- typically a whole
reproduction on the Warp backend, the GPU check's ``quick-warp`` -- and says where its time went:

* ``models_at_once`` -- how many models were inside a chunk at once, averaged over the time any
  was (``mean``), and at most (``max``);
* ``ms_per_step`` -- a steady chunk's wall time per step (chunks that compiled or captured graphs
  left out), step-weighted, by how many models stepped at once during it (its time-weighted mean,
  itself included: ``1`` is [1, 2), then ``2-3``, ``4-7``, ``8-15``, ``16+``): the H200's ~8x
  slowdown with ~20 models (2026-11-27) would show as the ``16+`` figure against the ``1`` one.
  On Warp's CPU device a chunk's time includes its wait for the device (one model steps at a time);
* ``structures_at_once`` -- how many distinct model structures (sizes and time step) were stepping
  at once, averaged like ``models_at_once``: their ratio bounds what gathering concurrent models of
  one structure into one model could remove (an upper bound: their runs' options, durations and
  start times differ too);
* ``host_share`` -- of each model's life (its first chunk's start to its last chunk's end), the part
  outside its chunks (its batch's host work between chunks, or another model of the same batch
  stepping), over every model;
* ``no_model_s`` -- time within the span when no model was stepping (the cores' lone swimmers, the
  studies' looks, kernel compilation outside a chunk);
* ``joinable`` -- for a window W of 1 s and 5 s, the models whose first chunk began within W after
  an earlier model's of the same structure (``models``, and their share of the world-steps): those a
  gatherer waiting W for same-structure batches could have stepped as worlds of that earlier model
  (again a bound: options and durations may differ);
* ``studies`` -- per study (the first part of a model's ``label``, the sweep its gathered batch
  stepped for; ``-`` for models without one): its models, sweeps and world-steps, and when its first
  chunk began and its last ended (s from the timeline's first chunk): on a GPU, where every study
  runs at once, the study that ends last is the reproduction's chain.  And its chain of steps: its
  models in ``waves`` (a model whose first chunk began after every earlier model of the study had
  ended starts the next wave: a look that waited for the one before), ``chain_steps`` the sum over
  the waves of the most steps a model of the wave took -- steps that had to follow one another, so
  the study cannot take less than ``chain_steps`` times a step's time on that device.

:func:`summarise` returns those as a dict (the GPU check stores it with each reproduction).
"""

from __future__ import annotations

import argparse
import gzip
import json
from pathlib import Path

import numpy as np

BINS = ((1, 2, "1"), (2, 4, "2-3"), (4, 8, "4-7"), (8, 16, "8-15"), (16, np.inf, "16+"))


def load(path: str | Path) -> list[dict]:
    """The timeline's models (FILE, or FILE.gz): ``{"model": (pid, group), "structure", "nworld", "device", "label",
    "chunks": (n, 4) array of [start_unix_s, wall_s, steps, first]}``, their lines joined, chunks in time order
    (``label`` "" in timelines written before it was recorded)."""
    models: dict = {}
    path = Path(path)
    raw = path.read_bytes()
    text = (gzip.decompress(raw) if path.suffix == ".gz" else raw).decode("utf-8")
    for line in text.splitlines():
        if not line.strip():
            continue
        x = json.loads(line)
        key = (x["pid"], x["group"])
        m = models.setdefault(key, {"model": key, "structure": tuple(x["structure"]), "nworld": x["nworld"],
                                    "device": x["device"], "label": x.get("label", ""), "chunks": []})
        m["chunks"] += x["chunks"]
    for m in models.values():
        c = np.asarray(m["chunks"], dtype=float).reshape(-1, 4)
        m["chunks"] = c[np.argsort(c[:, 0], kind="stable")]
    return list(models.values())


def _occupancy(starts: np.ndarray, ends: np.ndarray, labels: np.ndarray):
    """The step functions of the number of intervals open, and of distinct ``labels`` among them:
    (breakpoints t[0..n], count and distinct on each [t[i], t[i+1]))."""
    t = np.unique(np.concatenate([starts, ends]))
    count = np.zeros(len(t) - 1, dtype=int)
    distinct = np.zeros(len(t) - 1, dtype=int)
    i0, i1 = np.searchsorted(t, starts), np.searchsorted(t, ends)
    for lab in np.unique(labels):
        cover = np.zeros(len(t), dtype=int)
        sel = labels == lab
        np.add.at(cover, i0[sel], 1)
        np.add.at(cover, i1[sel], -1)
        open_ = np.cumsum(cover)[:-1]
        count += open_
        distinct += open_ > 0
    return t, count, distinct


def joinable(models: list[dict], window_s: float) -> dict:
    """The models whose first chunk began within ``window_s`` after an earlier same-structure model's."""
    firsts: dict = {}
    for m in models:
        if len(m["chunks"]):
            firsts.setdefault(m["structure"], []).append((float(m["chunks"][0, 0]), m))
    n, ws, total = 0, 0.0, 0.0
    for group in firsts.values():
        group.sort(key=lambda x: x[0])
        for i, (t, m) in enumerate(group):
            w = float((m["chunks"][:, 2] * m["nworld"]).sum())
            total += w
            if i and t - group[i - 1][0] <= window_s:
                n, ws = n + 1, ws + w
    return {"models": n, "world_step_share": ws / total if total else 0.0}


def by_study(models: list[dict]) -> dict:
    """Per study (a model's ``label`` up to its first ``/``; ``-`` without one): ``{"models", "sweeps",
    "world_steps", "first_s", "last_s", "waves", "chain_steps"}``, times from the timeline's first chunk,
    in order of ending (the module's docstring says what the waves are)."""
    live = sorted((m for m in models if len(m["chunks"])), key=lambda m: float(m["chunks"][0, 0]))
    if not live:
        return {}
    t0 = float(live[0]["chunks"][0, 0])
    out: dict = {}
    for m in live:
        label = m.get("label") or "-"
        s = out.setdefault(label.split("/")[0], {"models": 0, "sweeps": set(), "world_steps": 0,
                                                 "first_s": np.inf, "last_s": -np.inf, "waves": []})
        c = m["chunks"]
        begin, end, steps = float(c[0, 0]) - t0, float((c[:, 0] + c[:, 1]).max()) - t0, int(c[:, 2].sum())
        if s["waves"] and begin < s["last_s"]:  # began while an earlier model of the study stepped
            s["waves"][-1] = max(s["waves"][-1], steps)
        else:
            s["waves"].append(steps)
        s["models"] += 1
        s["sweeps"].add(label)
        s["world_steps"] += int((c[:, 2] * m["nworld"]).sum())
        s["first_s"] = min(s["first_s"], begin)
        s["last_s"] = max(s["last_s"], end)
    return {k: {**v, "sweeps": len(v["sweeps"]), "waves": len(v["waves"]), "chain_steps": int(sum(v["waves"]))}
            for k, v in sorted(out.items(), key=lambda kv: kv[1]["last_s"])}


def summarise(models: list[dict]) -> dict:
    """Where the models' time went (the module's docstring says what each figure is)."""
    chunks = [m["chunks"] for m in models if len(m["chunks"])]
    if not chunks:
        return {"models": len(models), "chunks": 0}
    structures = {s: i for i, s in enumerate(dict.fromkeys(m["structure"] for m in models))}
    c = np.concatenate(chunks)
    lab = np.concatenate([np.full(len(m["chunks"]), structures[m["structure"]]) for m in models if len(m["chunks"])])
    nworld = np.concatenate([np.full(len(m["chunks"]), m["nworld"]) for m in models if len(m["chunks"])])
    start, wall, steps, first = c[:, 0] - c[:, 0].min(), c[:, 1], c[:, 2], c[:, 3] > 0  # from the first start
    end = start + wall
    t, count, distinct = _occupancy(start, end, lab)
    dt = np.diff(t)
    busy = count > 0
    span = float(end.max() - start.min())
    # each chunk's mean number of models stepping at once (itself included), from the step function
    cum = np.concatenate([[0.0], np.cumsum(count * dt)])
    at = (np.interp(end, t, cum) - np.interp(start, t, cum)) / np.maximum(wall, 1e-12)
    at = np.where(wall > 0, at, 1.0)
    steady = ~first & (steps > 0)
    per_bin = {}
    for lo, hi, name in BINS:
        sel = steady & (at >= lo - 1e-6) & (at < hi - 1e-6)  # Unix times: ~1e-7 s apart
        if sel.any():
            per_bin[name] = {"ms_per_step": 1e3 * float(wall[sel].sum() / steps[sel].sum()), "chunks": int(sel.sum()),
                             "steps": int(steps[sel].sum())}
    life = sum(float(m["chunks"][-1, 0] + m["chunks"][-1, 1] - m["chunks"][0, 0]) for m in models if len(m["chunks"]))
    inside = float(wall.sum())
    return {
        "models": len(models), "structures": len(structures), "chunks": int(len(c)), "span_s": span,
        "world_steps": int((steps * nworld).sum()),
        "world_steps_per_s": float((steps * nworld).sum() / span) if span else None,
        "first_chunks_s": float(wall[first].sum()),
        "models_at_once": {"mean": float((count * dt)[busy].sum() / dt[busy].sum()) if busy.any() else 0.0,
                           "max": int(count.max())},
        "structures_at_once": {"mean": float((distinct * dt)[busy].sum() / dt[busy].sum()) if busy.any() else 0.0,
                               "max": int(distinct.max())},
        "ms_per_step": per_bin,
        "host_share": (life - inside) / life if life > 0 else None,
        "no_model_s": float(dt[~busy].sum()),
        "joinable": {f"{w:g}s": joinable(models, w) for w in (1.0, 5.0)},
        "studies": by_study(models),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("timeline")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    a = p.parse_args()
    s = summarise(load(a.timeline))
    if a.json:
        print(json.dumps(s))
        return
    for k, v in s.items():
        print(f"{k}: {v}")


if __name__ == "__main__":
    main()
