"""The staging engine: :func:`run_study` runs a study in looks, the same way for every study.

Each look runs the study's plan at that look (:func:`stage_plans`: the study's declared stages, or its
plan's :func:`~._protocol.staged` grids thinned), with the plan of each part its claims read frozen once
they are all final (:func:`part_plans`), judges its claims on intervals at the look's level, and adds a
look only while a claim is undecided.  It collects failed runs, wall time and provenance (the package
version, the code hash of every sweep and of the study) and writes, atomically, into ``OUT``::

    NAME.nc    the dataset (netCDF; units on every variable; provenance in attrs)
    NAME.png   the figure
    NAME.pdf   the figure, vector
    NAME.json  summary, claims with verdicts, failures, sweeps (identity, runs
               computed / reused), looks, wall time, configuration, identity, provenance

A study's ``identity`` (mode, seed, package version, hash of the study's code) tells
:func:`~._registry.is_current` whether files in a folder were made by this code with these settings;
sweeps recompute whatever was computed by other code or arguments (:mod:`undulate.sweep`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import sys
import time
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import stats
from ..errors import UndulateError
from ..execution import Execution, prefetch, substitution_note, using
from ..params import _flag
from ..provenance import provenance
from ._context import StudyConfig, StudyContext
from ._protocol import FAILS, HOLDS, NO_RESULT, STAGED, UNDECIDED, explain, judge
from ._registry import describe, identity

if TYPE_CHECKING:  # heavy imports stay lazy
    import xarray as xr
    from matplotlib.figure import Figure

    from .. import _walltime
    from ._protocol import Study

__all__ = ["run_study", "run_ahead", "stage_plans", "plan_looks", "part_plans", "PartPlans"]

@dataclass(frozen=True)
class PartPlans:
    """Where each part of a study's runs stands at a look (:func:`part_plans`)."""

    declared: frozenset[str]
    """Every part the study's claims and explanations read."""
    plans: dict[str, Any]
    """``part -> plan`` of the frozen parts: the plan of the look from which they are frozen."""
    frozen_at: dict[str, int]
    """``part -> look`` (1-based) of the frozen parts."""
    not_run: frozenset[str]
    """The parts only unneeded explanations read."""


def part_plans(info: Study, plans: Sequence[Any], final_claims: dict[str, int],
               final_explanations: dict[tuple[str, str], int],
               needs: Callable[[str, str], bool]) -> PartPlans:
    """Which plan each part of ``info``'s runs follows at the next look: a part every reader of which is
    final (a claim in ``final_claims``, claim -> the look from which its runs are final; an explanation
    that ``needs`` and that is in ``final_explanations``, ``(study, claim) -> look``) keeps the plan of
    the latest such look (``plans``: the study's stages); a part that only explanations read none of
    which ``needs`` is not run; every other part follows the look's own plan."""
    at: dict[str, list[int | None]] = {}
    for c in info.claims:
        for part in c.reads:
            at.setdefault(part, []).append(final_claims.get(c.claim))
    for e in info.explanations:
        needed = needs(e.study, e.claim)
        for part in e.reads:
            at.setdefault(part, [])
            if needed:
                at[part].append(final_explanations.get((e.study, e.claim)))
    frozen = {part: max(k) for part, k in at.items() if k and all(x is not None for x in k)}  # type: ignore
    return PartPlans(frozenset(at), {part: plans[k - 1] for part, k in frozen.items()}, frozen,
                     frozenset(part for part, k in at.items() if not k))


def _jsonable(obj: Any) -> Any:
    """Plain JSON types; numpy scalars and arrays unwrapped, non-finite floats -> None."""
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if hasattr(obj, "to_dict") and callable(obj.to_dict):  # Estimate, LineFit
        return _jsonable(obj.to_dict())
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    if obj is None or isinstance(obj, (bool, int, float, str)):
        return obj
    raise UndulateError(f"summary value {obj!r} ({type(obj).__name__}) is not JSON-able")


def _check_units(name: str, ds: xr.Dataset) -> None:
    missing = [str(k) for k, v in {**ds.coords, **ds.data_vars}.items()
               if v.dtype.kind in "iufc" and "units" not in v.attrs]
    if missing:
        raise UndulateError(f"study {name!r}: variables without a 'units' attribute: {missing}")


def _write_all(name: str, ds: xr.Dataset, figure: Figure, doc: dict[str, Any], out_dir: Path) -> Path:
    """Write every file through :func:`undulate._io.atomic_output`; they are moved into
    place only when all of them were written, the JSON last (its presence marks completion)."""
    import contextlib

    from .._io import atomic_output, netcdf_bytes, write_bytes

    ds = ds.copy()
    ds.attrs.update({"study": name, "study_config": json.dumps(doc["config"], sort_keys=True),
                     "study_identity": json.dumps(doc["identity"], sort_keys=True),
                     "study_sweeps": json.dumps(_jsonable(doc["sweeps"])), **doc["provenance"]})
    text = json.dumps(_jsonable(doc), indent=2, allow_nan=False) + "\n"
    with contextlib.ExitStack() as stack:  # exits (renames) in reverse order: the json last
        tmp_json = stack.enter_context(atomic_output(out_dir / f"{name}.json"))
        tmp_nc = stack.enter_context(atomic_output(out_dir / f"{name}.nc"))
        write_bytes(tmp_nc, netcdf_bytes(ds), out_dir / f"{name}.nc")  # compressed; a full disk: WriteError
        for ext in ("png", "pdf"):
            tmp = stack.enter_context(atomic_output(out_dir / f"{name}.{ext}"))
            figure.savefig(tmp, format=ext, dpi=150 if ext == "png" else None)  # a full disk: WriteError
        write_bytes(tmp_json, text.encode("utf-8"), out_dir / f"{name}.json")
    return out_dir / f"{name}.nc"


def _timing(ctx: StudyContext, here: _walltime.Tally, thread_cpu_s: float) -> dict[str, Any]:
    """Physics time of a study: inside ``mujoco.rollout`` in this process (``here``: serial sweeps
    and direct simulations) plus what its sweeps' worker processes report; ``thread_cpu_s``: the CPU
    time of the thread that ran the study here (its serial runs, summaries, judging, figure, files).
    Measured, not a result."""
    away = [s["timing"] for s in ctx.sweeps if s.get("timing", {}).get("executor") not in (None, "serial")]
    return {"physics_s": here.seconds + sum(t["physics_s"] for t in away), "thread_cpu_s": thread_cpu_s,
            "steps": here.steps + sum(t["steps"] for t in away),
            "physics_in_workers_s": sum(t["physics_s"] for t in away),
            "runs_in_workers_wall_s": sum(t["runs_wall_s"] for t in away),
            "n_runs_computed": sum(s["n_computed"] for s in ctx.sweeps)}


def run_study(name: str, out_dir: str | os.PathLike, quick: bool = False,
              scheduler: str | None = None, seed: int = 0, progress: bool = True,
              workers: int | None = None, execution: Execution | None = None,
              max_looks: int | None = None) -> Path:
    """Run study ``name`` and write its files into ``out_dir`` (created if needed).

    Returns ``out_dir/NAME.nc``; beside it ``NAME.png``, ``NAME.pdf`` and
    ``NAME.json``, each whole or not at all.  Sweeps finished earlier by the
    same code and arguments are reused; anything else is computed.  An
    unknown ``name`` raises :class:`~undulate.errors.ParameterError`.
    ``workers``: local worker processes (default: every core this process may
    use), kept warm across the study's sweeps (:func:`undulate.sweep.warm_workers`).
    ``execution``: how its runs are executed (:class:`undulate.execution.Execution`, which then holds
    the workers and scheduler; default: the settings in effect with ``workers`` and ``scheduler``).
    ``max_looks``: stop after at most this many looks (None: every look while a claim is undecided;
    :attr:`~._context.StudyConfig.max_looks`).
    Another process writing to ``out_dir`` (a reproduction or a study) is a ParameterError before
    anything is written (:func:`undulate._outdir.writing_to`).
    """
    info = describe(name)
    config = StudyConfig(out_dir=out_dir, quick=quick, scheduler=scheduler, seed=seed,
                         workers=workers, execution=execution, max_looks=max_looks)
    _flag("progress", progress)
    out = config.out_dir
    from .._outdir import writing_to
    from ..sweep import warm_workers

    with writing_to(out, "out_dir"), warm_workers(config.workers), using(config.execution):
        return _run_study(info, name, config, out, progress)


def run_ahead(name: str, out_dir: str | os.PathLike, quick: bool = False, scheduler: str | None = None,
              seed: int = 0, workers: int | None = None, execution: Execution | None = None,
              max_looks: int | None = None) -> dict[str, Any]:
    """An explaining study's runs before the studies it explains have finished (the reproduction does
    this where it runs wide, :func:`undulate.execution.runs_ahead`, so that the explaining study does not start its long chains
    only once the others end): a stage's dataset with every explanation taken as needed, into the
    stores the study reads when it then runs.  On the Warp backend on a GPU its last stage's (a few
    more worlds cost the device little, and the study steps its last stage first there,
    :func:`_prefetch`); elsewhere its first stage's (later stages cost the cores their runs, and are
    made only if a look needs them).  Nothing is
    written but the runs, and nothing is judged: the study's own run, once the studies it explains
    have finished, reads what its looks need from the stores (a run's result is a function of its
    parameters and seed) and computes what is missing; runs it skips are left unread.  Returns what
    was computed (``n_runs``, ``n_computed``, ``wall_s``)."""
    info = describe(name)
    config = StudyConfig(out_dir=out_dir, quick=quick, scheduler=scheduler, seed=seed,
                         workers=workers, execution=execution, max_looks=max_looks)
    config.out_dir.mkdir(parents=True, exist_ok=True)
    ctx = StudyContext(config, name, progress=False, explanations=info.explanations)
    # the verdicts are not known yet: every explanation (in quick mode, every one that is not a finding)
    ctx.needs_explanation = ctx.may_run_for
    t0 = time.perf_counter()
    plans = stage_plans(info, config.quick, config.max_looks)
    ctx.parts = part_plans(info, plans, {}, {}, ctx.needs_explanation)
    with using(config.execution):
        info.dataset(ctx, plans[-1] if _prefetching(config.execution) else plans[0])
    return {"n_runs": sum(s["n_runs"] for s in ctx.sweeps), "n_computed": sum(s["n_computed"] for s in ctx.sweeps),
            "wall_s": time.perf_counter() - t0}


def plan_looks(plan: Any, quick: bool) -> tuple[Any, ...]:
    """The looks of ``plan`` (:func:`~._protocol.staged`): ``plan`` with each staged field thinned, one plan a look,
    the last ``plan`` itself; ``(plan,)`` for a plan with no staged field."""
    from ._stages import strides, thinned

    fields = ([(f.name, f.metadata[STAGED]) for f in dataclasses.fields(plan) if STAGED in f.metadata]
              if dataclasses.is_dataclass(plan) and not isinstance(plan, type) else [])
    if not fields:
        return (plan,)
    steps = {name: tuple(r * s for s in strides(quick)) + ((1,) if r > 1 else ()) for name, r in fields}
    if len({len(v) for v in steps.values()}) != 1:
        raise UndulateError(f"the staged fields of {type(plan).__name__} have different numbers of looks: {steps}")
    grids = {name: thinned(getattr(plan, name), steps[name]) for name, _ in fields}
    n = len(next(iter(steps.values())))
    return tuple(dataclasses.replace(plan, **{name: g[k] for name, g in grids.items()}) for k in range(n))


def stage_plans(info: Study, quick: bool, max_looks: int | None = None) -> tuple[Any, ...]:
    """The plans of ``info``'s looks in this mode: its declared :attr:`~._protocol.Study.stages`, else those of its
    plan's staged fields (:func:`plan_looks`; one, ``plan(quick)``, if none); the first ``max_looks`` of them
    where that is given (:attr:`~._context.StudyConfig.max_looks`)."""
    plans = tuple(info.stages(quick)) if info.stages is not None else plan_looks(info.plan(quick), quick)
    if not plans:
        raise UndulateError(f"study {info.name!r} declares no stages")
    return plans if max_looks is None else plans[:max_looks]


def _open(claims: list[dict[str, Any]], explanations: list[dict[str, Any]], growth_left: float,
          futile: Collection[str] = ()) -> list[str]:
    """What another stage may still decide after a look: undecided claims, except those whose interval
    would need more than ``growth_left`` times the runs it rests on to be decided at the last look's level
    (:func:`undulate.stats.runs_needed`; quick mode's cap cannot decide them:
    a futility stop, which never turns a claim into ``holds`` or ``fails``) and those an earlier look
    found futile (``futile``: their runs stay where they were, :func:`part_plans`);
    claims with ``no result`` (too few design points or runs with a result for an interval: more runs
    may give one); and explanations whose claim fails (the others are moot:
    :meth:`~._context.StudyContext.needs_explanation`)."""
    def decidable(c: dict[str, Any]) -> bool:
        g = c.get("growth_needed")
        return c["claim"] not in futile and (g is None or g <= growth_left)

    return ([c["claim"] for c in claims if (c["verdict"] == UNDECIDED and decidable(c)) or c["verdict"] == NO_RESULT]
            + [f"explanation of {e['claim']}" for e in explanations if e["shown"] is None and e["needed"]])


def _growth_left(n_plans: int, look: int, quick: bool) -> float:
    """How many times more runs the quick cap holds than look ``look`` (1-based) of ``n_plans``: the
    stride of that look when the study's stages follow :mod:`._stages` (``n_plans`` strides), else
    unbounded.  Full mode is unbounded: it decides, so it runs to its cap while a claim is undecided
    (the estimate, :func:`undulate.stats.runs_needed`, assumes the value stays put, and a full-mode claim
    whose estimate sat on its boundary after 13 of 49 runs was decided by all 49)."""
    from ._stages import strides

    s = strides(quick)
    return float(s[look - 1]) if quick and n_plans == len(s) else math.inf


def _prefetching(execution: Execution) -> bool:
    """Whether studies under ``execution`` step their last stage first (:func:`_prefetch`): on the Warp
    backend on a GPU (:func:`undulate.execution.prefetch`; its device resolved only where the setting
    leaves it to the device)."""
    if execution.backend != "warp":
        return False
    device = execution.device
    if execution.prefetch is None and device is None:  # the default device: the machine's
        from ..simulation import backend

        device = backend(execution.backend).resolve_device(device)
    return prefetch(device, execution)


def _engine_note(name: str, execution: Execution, progress: bool) -> str | None:
    """Which of the study's runs step on another engine than the one asked for
    (:func:`undulate.execution.substitution_note`: lone swimmers and small batches asked of Warp on the
    cores), said once in the study's log (standard error with ``progress``, else the logger
    ``undulate.studies``) and returned for its JSON (``engines``); None where every run steps on the
    engine asked for.  Each such run's Dataset says so too (attrs ``engine``, ``engine_requested``)."""
    if execution.backend == "mujoco":
        return None
    from ..simulation import backend

    note = substitution_note(execution, backend(execution.backend).resolve_device(execution.device))
    if note is not None:
        if progress:
            print(f"{name}: {note}", file=sys.stderr, flush=True)
        else:
            import logging

            logging.getLogger("undulate.studies").info("%s: %s", name, note)
    return note


def _prefetch(info: Study, ctx: "StudyContext", plans: tuple[Any, ...]) -> dict[str, Any] | None:
    """On the Warp backend on a GPU (:func:`_prefetching`), the last stage's runs before the first look:
    a stage costs the device about the same whatever its number of worlds, so every stage's runs
    (nested: the last stage holds them all) are stepped in one go and the looks then read them from the
    sweep stores.  The looks, their levels and their verdicts are the staged plan's (a look never sees a
    run its stage would not have made); runs a decided claim did not need are computed and left unread.
    None on the MuJoCo backend, on Warp's CPU device, or with one stage; else what was computed
    (``n_runs``, ``n_computed``, ``wall_s``)."""
    if len(plans) < 2 or not _prefetching(ctx.config.execution):
        return None
    t0, first = time.perf_counter(), len(ctx.sweeps)
    info.dataset(ctx, plans[-1])
    mine = ctx.sweeps[first:]
    for s in mine:  # kept in the study's sweeps (its timing, its runs computed), marked
        s["prefetch"] = True
    return {"stage": len(plans), "n_runs": sum(s["n_runs"] for s in mine),
            "n_computed": sum(s["n_computed"] for s in mine), "wall_s": time.perf_counter() - t0}


def _keep_decided(rows: list[dict[str, Any]], decided: dict[Any, dict[str, Any]], key: Callable[[dict], Any],
                  decision: Callable[[dict], Any], look: dict[str, Any]) -> list[dict[str, Any]]:
    """``rows`` of this look, with every claim (or explanation) decided at an earlier look kept decided,
    as in a group-sequential design: the later looks run for what is still open and never reopen it.

    ``decision(row)``: the row's decision (e.g. ``holds`` / ``fails``), None while open.  The first look
    that decides a row marks it ``decided_at`` (that look's ``stage``, ``of`` and ``confidence_level``);
    a later look that decides it the same way, on more runs, replaces the row shown (its
    ``measured_at_stage``), and one that does not leaves the deciding row as it was.  Every look's
    intervals are valid at its level with the family-wise 95 % over the looks (Bonferroni), so any look
    that decides it may stand for it.  ``decided`` (key -> row) is updated in place."""
    out = []
    for r in rows:
        k, d = key(r), decision(r)
        if k in decided:
            first = decided[k]
            if d is not None and d == decision(first):
                decided[k] = {**r, "decided_at": {**first["decided_at"], "measured_at_stage": look["stage"]}}
        elif d is not None:
            decided[k] = {**r, "decided_at": {**look, "measured_at_stage": look["stage"]}}
        out.append(decided.get(k, {**r, "decided_at": None}))
    return out


@dataclass
class _Decisions:
    """What a study's looks so far decided (claims that hold or fail, explanations shown or refuted: each
    row as :func:`_keep_decided` keeps it) and found futile (claim -> the look that found it so)."""

    claims: dict[Any, dict[str, Any]] = field(default_factory=dict)
    explanations: dict[Any, dict[str, Any]] = field(default_factory=dict)
    futile_at: dict[str, int] = field(default_factory=dict)

    def keep(self, claims: list[dict[str, Any]], explanations: list[dict[str, Any]],
             at: dict[str, Any]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
        """This look's rows with every earlier decision kept (:func:`_keep_decided`)."""
        claims = _keep_decided(claims, self.claims, lambda c: c["claim"],
                               lambda c: c["verdict"] if c["verdict"] in (HOLDS, FAILS) else None, at)
        explanations = _keep_decided(explanations, self.explanations, lambda e: (e["study"], e["claim"]),
                                     lambda e: e["shown"], at)
        return claims, explanations

    def mark_futile(self, claims: list[dict[str, Any]], still: list[str], look: int) -> None:
        """Undecided claims no longer open at ``look`` are futile from the first look that found them so."""
        for c in claims:
            if c["verdict"] == UNDECIDED and c["claim"] not in still:
                self.futile_at.setdefault(c["claim"], look)

    def parts(self, info: Study, plans: Sequence[Any], needs: Callable[[str, str], bool]) -> PartPlans:
        """The plan of each part at the next look (:func:`part_plans`): a claim is final once decided, or
        futile (from the look that found it so: its runs stopped there); an explanation once decided."""
        final_claims = {**{k: c["decided_at"]["stage"] for k, c in self.claims.items()}, **self.futile_at}
        final_explanations = {k: e["decided_at"]["stage"] for k, e in self.explanations.items()}
        return part_plans(info, plans, final_claims, final_explanations, needs)


def _look_row(at: dict[str, Any], sweeps: list[dict[str, Any]], verdicts: dict[str, str], still: list[str],
              claims: list[dict[str, Any]], parts: PartPlans) -> dict[str, Any]:
    """One look's row of the study JSON's ``stages``: its runs, its own verdicts, what stayed open, what
    was futile, and which plan parts it kept frozen or did not run."""
    return {**at, "n_runs": sum(s["n_runs"] for s in sweeps), "n_computed": sum(s["n_computed"] for s in sweeps),
            "verdicts": verdicts, "undecided": still,
            "futile": [c["claim"] for c in claims if c["verdict"] == UNDECIDED and c["claim"] not in still],
            "frozen_parts": dict(sorted(parts.frozen_at.items())), "parts_not_run": sorted(parts.not_run)}


def _run_study(info: Study, name: str, config: StudyConfig, out: Path, progress: bool) -> Path:
    """Run the study's stages until nothing it judges is undecided (or the last stage ran).

    Look k of K forms its intervals at :func:`undulate.stats.look_levels`\\ (K)[k] (Bonferroni over
    the looks, so a verdict taken at any look keeps the family-wise 95 %); the runs of every earlier
    stage are reused by the sweeps (content-keyed stores).  A claim that holds or fails at a look, and
    an explanation shown or refuted there, stays decided however the later looks, run for what is still
    undecided, would judge it; its row is the last look's that decided it the same way
    (:func:`_keep_decided`: ``decided_at``).  Each look's own verdicts are in ``stages``.  The study's
    files hold the last look.
    """
    from .. import _walltime

    t0, cpu0 = time.perf_counter(), time.thread_time()
    ctx = StudyContext(config, name, progress=progress, explanations=info.explanations)
    engines = _engine_note(name, config.execution, progress)
    plans = stage_plans(info, config.quick, config.max_looks)
    levels = stats.look_levels(len(plans))
    looks: list[dict[str, Any]] = []
    decisions = _Decisions()
    with _walltime.meter() as here:  # what this process simulates (serial sweeps, direct runs)
        ctx.parts = decisions.parts(info, plans, ctx.needs_explanation)
        prefetched = _prefetch(info, ctx, plans)
        for k, (plan, level) in enumerate(zip(plans, levels), start=1):
            first = len(ctx.sweeps)
            ctx.parts = decisions.parts(info, plans, ctx.needs_explanation)
            with stats.at_level(level, plan_at=levels[-1]):  # runs needed: to decide at the cap's look
                ds = info.dataset(ctx, plan)
                summary = info.summary(ds)
                claims = [{**c, "reference": info.reference} for c in judge(name, info.claims, summary)]
                explanations = [{**e, "needed": ctx.needs_explanation(e["study"], e["claim"])}
                                for e in explain(name, info.explanations, summary)]
            verdicts = {c["claim"]: c["verdict"] for c in claims}  # this look's own
            at = {"stage": k, "of": len(plans), "confidence_level": level}
            claims, explanations = decisions.keep(claims, explanations, at)
            still = _open(claims, explanations, _growth_left(len(plans), k, config.quick), decisions.futile_at)
            decisions.mark_futile(claims, still, k)
            looks.append(_look_row(at, ctx.sweeps[first:], verdicts, still, claims, ctx.parts))
            if not still:
                break
    claims = [c if c["decided_at"] is None else
              {**c, "decided_at": {**c["decided_at"], "later_verdicts": [s["verdicts"].get(c["claim"]) for s in
                                                                         looks[c["decided_at"]["stage"]:]]}}
              for c in claims]
    _check_units(name, ds)
    figure = info.figure(ds)
    timing = _timing(ctx, here, time.thread_time() - cpu0)  # the files' writing is left out
    doc = {
        "study": name,
        "summary": summary,
        "claims": claims,
        "explanations": explanations,
        "stages": looks,
        "prefetched": prefetched,
        "engines": engines,
        "n_failed": len(set(ctx.failures)),
        "failures": list(dict.fromkeys(ctx.failures))[:50],  # a failed run is met again at each later stage
        "sweeps": ctx.sweeps,
        "n_computed": sum(s["n_computed"] for s in ctx.sweeps),
        "wall_s": time.perf_counter() - t0,
        "timing": timing,
        "config": config.to_dict(),
        "identity": identity(name, config),
        "provenance": provenance(),
        "files": [f"{name}.{ext}" for ext in ("nc", "png", "pdf")],
    }
    return _write_all(name, ds, figure, doc, out)
