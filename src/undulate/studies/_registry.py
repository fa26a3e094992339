"""The study protocol and registry: one way to state, run, cache, judge and save every study.

A study module states, in this order (read ``pairs.py`` as the example)::

    plan(quick) -> Plan                    # its grids and constants, quick and full
    dataset(ctx, plan) -> xarray.Dataset   # runs its sweeps through ctx, assembles the data
    summary(ds) -> dict                    # PURE: numbers (with uncertainties) from the data
    CLAIMS = (Claim(...), ...)             # PURE functions of the summary -> Verdict
    figure(ds) -> Figure

and registers them with ``register(Study(name=..., plan=plan, dataset=...,
summary=summary, claims=CLAIMS, figure=figure))``.  Adding the module under
``undulate/studies/`` is the only step: the registry imports every public module
of the package (:func:`_load`).  Studies are listed and reproduced in the order of
their :attr:`Study.order` (by default the paper's figure number; see there).

The registry (:func:`run_study`) does the rest, the same way for every
study: it runs and caches the sweeps a study asks for (``ctx.sweep``; one
store layout ``OUT/.sweeps/STUDY/PART-{quick|full}-seedS``), measures the
shared quantities once (``ctx.lone_swimmer``: one free swimmer per gait and
ground, one definition of the amplitude A, stored in ``OUT/.sweeps/_lone``),
collects failed runs, wall time and provenance (the package version, the
code hash of every sweep and of the study), judges the claims and writes,
atomically, into ``OUT``::

    NAME.nc    the dataset (netCDF; units on every variable; provenance in attrs)
    NAME.png   the figure
    NAME.pdf   the figure, vector
    NAME.json  summary, claims with verdicts, failures, sweeps (identity, runs
               computed / reused), wall time, configuration, identity, provenance

A study's ``identity`` (mode, seed, package version, hash of the study's
code) tells :func:`is_current` whether files in a folder were made by this
code with these settings; sweeps recompute whatever was computed by other
code or arguments (:mod:`undulate.sweep`).
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import math
import os
import pkgutil
import sys
import threading
import time
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import stats
from ..errors import ParameterError, UndulateError
from ..execution import Execution, prefetch, runs_here, runs_wide, settings, substitution_note, using
from ..params import _flag
from ..provenance import provenance

if TYPE_CHECKING:  # heavy imports stay lazy
    import xarray as xr
    from matplotlib.figure import Figure

    from .. import _walltime
    from ..sweep import Grid, SweepResult

__all__ = [
    "StudyConfig",
    "Study",
    "Claim",
    "SupersededCriterion",
    "Verdict",
    "StudyContext",
    "register",
    "names",
    "describe",
    "run_study",
    "judge",
    "identity",
    "is_current",
    "VERDICTS",
    "Explanation",
    "explain",
    "staged",
]

HOLDS, FAILS, UNDECIDED, NO_RESULT = "holds", "fails", "undecided", "no result"
VERDICTS = (HOLDS, FAILS, UNDECIDED, NO_RESULT)
"""A study's verdicts on a claim: its intervals lie inside the accepted region (``holds``), one lies
wholly outside (``fails``), none is outside and one straddles a boundary (``undecided``), or there is no
number to judge (``no result``)."""
EXPLAINED = "explained"
"""Not a study's verdict: :mod:`undulate.claims` turns a claim that ``fails`` into
``explained`` when some study's :class:`Explanation` of it was shown by that study's runs."""


@dataclass(frozen=True)
class StudyConfig:
    """How to run a study.

    ``out_dir``: where the study's files go (and its resumable sweep stores);
    ``quick``: the reduced plan that runs in minutes; ``scheduler``: a Dask
    scheduler address, or None for local processes; ``seed``: the root seed
    of every random draw; ``workers``: local worker processes (None: every
    core this process may use; results do not depend on it); ``execution``: how its runs are executed
    (:class:`undulate.execution.Execution`; None: the settings in effect with ``workers`` and
    ``scheduler``, :func:`undulate.execution.settings`).  ``workers`` and ``scheduler`` always
    read as ``execution``'s.
    """

    out_dir: Path
    quick: bool = False
    scheduler: str | None = None
    seed: int = 0
    workers: int | None = None
    execution: Execution | None = None

    def __post_init__(self):
        if isinstance(self.out_dir, bytes) or not isinstance(self.out_dir, str | os.PathLike):
            raise ParameterError("out_dir", "a folder's path (a str or os.PathLike)", type(self.out_dir).__name__)
        object.__setattr__(self, "out_dir", Path(self.out_dir))
        object.__setattr__(self, "quick", _flag("quick", self.quick))
        s = self.seed
        if isinstance(s, bool) or not isinstance(s, int | np.integer) or s < 0:
            raise ParameterError("seed", "an integer >= 0", s)
        object.__setattr__(self, "seed", int(s))
        ex = self.execution
        if ex is not None and (self.workers, self.scheduler) in ((None, None), (ex.workers, ex.scheduler)):
            object.__setattr__(self, "workers", None)  # theirs, read from it below
            object.__setattr__(self, "scheduler", None)
        ex = settings(ex, workers=self.workers, scheduler=self.scheduler)  # the scheduler's form checked now
        object.__setattr__(self, "execution", ex)
        object.__setattr__(self, "workers", ex.workers)
        object.__setattr__(self, "scheduler", ex.scheduler)

    def to_dict(self) -> dict[str, Any]:
        """What the study's JSON records of it (``config``): its folder, mode, scheduler, seed and workers
        (the engine is in its identity, :func:`identity`)."""
        return {"out_dir": str(self.out_dir), "quick": self.quick, "scheduler": self.scheduler, "seed": self.seed,
                "workers": self.workers}

    @property
    def mode(self) -> str:
        return "quick" if self.quick else "full"


# ------------------------------------------------------------------- claims
@dataclass(frozen=True)
class Verdict:
    """The judgement of one claim: ``verdict`` is one of :data:`VERDICTS`;
    ``measured``: the measured value(s) with uncertainty, as text; ``value``: the same as
    numbers (e.g. an :class:`~undulate.stats.Estimate` dict); ``reason``: why there is no
    result, or which boundary an undecided claim's interval straddles; ``runs_needed``: for an
    undecided claim, about how many runs its straddling interval would need to decide
    (:class:`~undulate.stats.Check`; None when unknown)."""

    verdict: str
    measured: str
    value: Any = None
    reason: str = ""
    runs_needed: int | None = None
    growth_needed: float | None = None
    """For an undecided claim: how many times more runs its straddling interval would need
    (``runs_needed`` over the runs it rests on; None when unknown)."""

    def __post_init__(self):
        if self.verdict not in VERDICTS:
            raise UndulateError(f"verdict must be one of {VERDICTS}, not {self.verdict!r}")

    @classmethod
    def judged(cls, ok: bool | None, measured: str, value: Any = None, reason: str = "") -> Verdict:
        """``ok``: True holds, False fails, None undecided (``reason`` then names the boundary)."""
        return cls(HOLDS if ok is True else FAILS if ok is False else UNDECIDED, measured, value, reason)

    @classmethod
    def of(cls, checks: Sequence[stats.Check], measured: str, value: Any = None, *,
           runs: int | None = None) -> Verdict:
        """The verdict of a claim with several criteria (:func:`undulate.stats.decide`): fails if one
        fails, undecided if none fails and one straddles, else holds.  An undecided verdict's reason
        names every straddled boundary; its ``runs_needed`` is the largest of theirs.  ``runs``: the runs
        the checks' estimates rest on, where their points are not runs (a group's neighbour pairs, two or
        three a run): ``runs_needed`` is then that many runs times the largest growth needed."""
        ok = stats.decide(checks)
        if ok is not None:
            return cls.judged(ok, measured, value)
        open_ = [c for c in checks if c.state is None]
        needed = [c.runs_needed for c in open_]
        n = None if None in needed else max(needed)  # type: ignore[type-var]
        growth = [c.growth_needed for c in open_]
        g = None if None in growth else max(growth)  # type: ignore[type-var]
        if runs is not None:
            n = None if g is None else int(math.ceil(runs * g - 1e-9))
        reason = "; ".join(c.text for c in open_)
        if n is not None:
            reason += f" (about {n} runs would decide it)"
        return cls(UNDECIDED, measured, value, reason, n, g)

    @classmethod
    def none(cls, reason: str, measured: str = "", value: Any = None) -> Verdict:
        return cls(NO_RESULT, measured or f"no result: {reason}", value, reason)


@dataclass(frozen=True)
class Claim:
    """A claim of the paper that a study checks.

    ``claim``: what is checked; ``paper``: the paper's statement;
    ``criterion``: the rule, stated on the 95 % intervals; ``judge``: a pure
    function of the study's summary returning a :class:`Verdict`.  A judge
    reads the summary's keys directly: a renamed key raises (the study fails
    loudly), it never turns into ``no result``.
    """

    claim: str
    paper: str
    criterion: str
    judge: Callable[[dict[str, Any]], Verdict] = field(repr=False, compare=False)
    quote: str = ""
    """The paper's own sentence that this claim tests, verbatim from ``paper.tex`` (LaTeX math kept as
    written); ``paper`` is its short paraphrase."""
    where: str = ""
    """Where the paper states it: its section and figure, e.g. ``"Sec. III.A, Fig. 3c"``."""
    superseded: tuple[SupersededCriterion, ...] = ()
    """Criteria this claim was judged by before (oldest first): each is judged on the same summary and
    shown beside the current verdict, so a changed criterion never hides the verdict the old one gives."""
    bands: dict[str, tuple[float | None, float | None]] = field(default_factory=dict, compare=False)
    """The criterion's accepted region of each number in the verdict's ``value``, for the claim's evidence
    figure (:mod:`undulate._evidence`): ``{key: (low, high)}`` (None: unbounded), ``key`` the number's own
    key in ``value`` (at any depth), ``"*"`` every number without its own; the judge, not this, decides."""
    evidence: Callable[[dict[str, Any]], Figure] | None = field(default=None, repr=False, compare=False)
    """A claim whose data needs its own picture: a function of the claim's row (``claims.json``'s, with
    ``value`` and ``explanation``) returning a Figure; None (the default): the generic evidence figure of
    :func:`undulate._evidence.evidence_figure`, drawn from ``value`` and :attr:`bands`."""
    reads: tuple[str, ...] = ()
    """The parts of the study's plan whose runs this claim's judge reads (names the study gives them,
    e.g. ``("xi=1",)``; asked for with :meth:`StudyContext.plan_for`).  Once every claim and needed
    explanation reading a part is final, the staging engine keeps that part's runs on the plan of the
    look that made them final (:func:`part_plans`).  Empty: the claim reads no part a look may freeze."""

    def __post_init__(self):
        _check_reads(self.reads, f"claim {self.claim!r}")


@dataclass(frozen=True)
class SupersededCriterion:
    """A criterion a claim no longer uses: ``criterion`` its text, ``judge`` the same kind of pure
    function of the study's summary as :attr:`Claim.judge`, ``why`` the reason it was replaced (the
    paper's words it did not test)."""

    criterion: str
    judge: Callable[[dict[str, Any]], Verdict] = field(repr=False, compare=False)
    why: str = ""


def _check_reads(reads: Any, what: str) -> None:
    """``reads`` must be a tuple of non-empty part names."""
    if not isinstance(reads, tuple) or not all(isinstance(r, str) and r.strip() for r in reads):
        raise ParameterError("reads", f"a tuple of the plan parts {what} reads (non-empty texts)", reads)


def judge(study: str, claims: tuple[Claim, ...], summary: dict[str, Any]) -> list[dict[str, Any]]:
    """Rows ``{study, claim, paper, criterion, measured, value, verdict, reason}`` for ``claims``."""
    rows = []
    for c in claims:
        v = c.judge(summary)
        if not isinstance(v, Verdict):
            raise UndulateError(f"claim {c.claim!r} of study {study!r} returned {type(v).__name__}, not Verdict")
        old = []
        for o in c.superseded:
            ov = o.judge(summary)
            if not isinstance(ov, Verdict):
                raise UndulateError(f"superseded criterion of claim {c.claim!r} of study {study!r} returned "
                                    f"{type(ov).__name__}, not Verdict")
            old.append({"criterion": o.criterion, "why": o.why, "verdict": ov.verdict, "measured": ov.measured,
                        "reason": ov.reason})
        rows.append({"study": study, "claim": c.claim, "paper": c.paper, "quote": c.quote, "where": c.where,
                     "criterion": c.criterion,
                     "measured": v.measured, "value": v.value, "verdict": v.verdict, "reason": v.reason,
                     "runs_needed": v.runs_needed, "growth_needed": v.growth_needed,
                     "superseded": old})
    return rows


@dataclass(frozen=True)
class Explanation:
    """A demonstrated cause of a claim that fails under the default model.

    ``study``/``claim``: the claim explained (its study's name and its exact
    ``Claim.claim`` text; :func:`undulate.claims.collect` matches on both);
    ``cause``: the cause in one sentence; ``check``: a pure function of the
    *explaining* study's summary returning ``(shown, measured, value)``:
    whether that study's own runs show the cause (True), refute it (False)
    or leave it undecided (None: an interval it rests on straddles its bound) (judged on 95 % intervals,
    e.g. "the claim's criterion fails with the default and holds with only
    this factor changed"), the evidence numbers as text, and as numbers.
    The explaining study's figure is the evidence figure.

    ``finding``: a finding about the failing claim, not an explanation of it (e.g. the paper's behaviour
    comes back only with several changes together): shown or not, it never turns ``fails`` into
    ``explained`` (:func:`undulate.claims.apply_explanations` lists it with the row as a finding).
    """

    study: str
    claim: str
    cause: str
    check: Callable[[dict[str, Any]], tuple[bool, str, Any]] = field(repr=False, compare=False)
    finding: bool = False
    reads: tuple[str, ...] = ()
    """The parts of the explaining study's plan whose runs :attr:`check` reads (as :attr:`Claim.reads`).
    A part only explanations read runs only while one of them is needed (its claim fails, or its verdict
    is unknown: :meth:`StudyContext.needs_explanation`); else the study is handed None for it."""

    def __post_init__(self):
        _check_reads(self.reads, f"the explanation of {self.claim!r}")


def explain(study: str, explanations: tuple[Explanation, ...], summary: dict[str, Any]) -> list[dict[str, Any]]:
    """Rows ``{study, claim, cause, finding, shown, measured, value, evidence_study, evidence_figure}``."""
    rows = []
    for e in explanations:
        shown, measured, value = e.check(summary)
        rows.append({"study": e.study, "claim": e.claim, "cause": e.cause, "finding": bool(e.finding),
                     "shown": None if shown is None else bool(shown),
                     "measured": measured, "value": value, "evidence_study": study,
                     "evidence_figure": f"{study}.png"})
    return rows


# ------------------------------------------------------------------- studies
@dataclass(frozen=True)
class Study:
    """A registered study (see the module docstring for the protocol)."""

    name: str
    description: str
    plan: Callable[[bool], Any] = field(repr=False, compare=False)
    """``plan(quick)``: the mode's whole plan (its cap: the last stage)."""
    dataset: Callable[[StudyContext, Any], xr.Dataset] = field(repr=False, compare=False)
    summary: Callable[[xr.Dataset], dict[str, Any]] = field(repr=False, compare=False)
    figure: Callable[[xr.Dataset], Figure] = field(repr=False, compare=False)
    claims: tuple[Claim, ...] = ()
    explanations: tuple[Explanation, ...] = ()
    paper_figure: str | None = None
    reference: str = "paper"
    """Whose claims the study judges: ``"paper"`` (the reproduced study) or ``"prx2021"`` (beyond
    the paper: synchronization through contact, Zhou, Hao & Gravish, Phys. Rev. X 11, 031051 (2021),
    judged against our candidate controllers).  The report and ``claims.json`` count them apart."""
    needs_simulation: bool = True
    module: str = ""
    stages: Callable[[bool], tuple[Any, ...]] | None = field(default=None, repr=False, compare=False)
    """``stages(quick)``: the mode's plan in stages, each containing the one before (its grids'
    points a superset, so a stage reuses every run made before it), the last equal to
    ``plan(quick)``.  The registry runs a stage only while one of the study's claims or
    explanations is undecided (:func:`run_study`).  None (the default, and all a new study needs): the
    looks of its plan's :func:`staged` fields (:func:`plan_looks`), or one stage, ``plan(quick)``."""
    order: float | None = None
    """Where the study comes in ``undulate studies``, the reproduction and the report
    (ascending; ties keep the order of registration: modules by name, then the order
    of ``register`` calls in a module).  None (the default) takes it from the study:
    its paper figure number; 90 for other paper material (``paper_figure`` not a
    number, e.g. "Methods"); 100 for a study beyond the paper's figures; 200 for a
    study that only explains other studies' claims (no claims of its own), whose
    explanations are judged on results the others made first."""

    def __str__(self) -> str:
        tags = [f"paper Fig. {self.paper_figure}"] if self.paper_figure else []
        tags.append("simulation" if self.needs_simulation else "theory only")
        return f"{self.description} [{'; '.join(tags)}]"


_REGISTRY: dict[str, Study] = {}
_REGISTERED: dict[str, int] = {}  # name -> its place among its module's register calls
_loaded = False


def register(study: Study) -> Study:
    """Register ``study`` under ``study.name`` (its module is recorded for the code hash)."""
    import inspect

    if study.name in _REGISTRY and _REGISTRY[study.name].dataset is not study.dataset:
        raise UndulateError(f"study {study.name!r} registered twice")
    if not study.module:
        mod = inspect.getmodule(study.dataset)
        study = dataclasses.replace(study, module=mod.__name__ if mod else "")
    if study.order is None:
        study = dataclasses.replace(study, order=_default_order(study))
    _REGISTERED.setdefault(study.name, sum(s.module == study.module for s in _REGISTRY.values()))
    _REGISTRY[study.name] = study
    return study


def _default_order(study: Study) -> float:
    """:attr:`Study.order` when the study declares none (see there)."""
    fig = (study.paper_figure or "").strip()
    if fig.isdigit():
        return float(fig)
    if fig:
        return 90.0
    return 200.0 if study.explanations and not study.claims else 100.0


def _load() -> None:
    """Import every public module of this package (names not starting with ``_``): each
    registers its studies.  Sorted by name, so registration order never depends on the
    file system."""
    global _loaded
    if _loaded:
        return
    package_path = sys.modules[__package__].__path__  # this package's folder(s), without an import edge to it
    for info in sorted(pkgutil.iter_modules(package_path), key=lambda m: m.name):
        if not info.name.startswith("_"):
            importlib.import_module(f"{__package__}.{info.name}")
    _loaded = True


def names() -> list[str]:
    """Registered study names, in the order of :attr:`Study.order` (the paper's)."""
    _load()
    # ties by module name, then register calls: not by which module some caller happened to import first
    return sorted(_REGISTRY, key=lambda name: (_REGISTRY[name].order, _REGISTRY[name].module, _REGISTERED[name]))


def describe(name: str) -> Study:
    """The :class:`Study` named ``name``; unknown names raise ParameterError."""
    _load()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ParameterError("study", "one of " + ", ".join(names()), name) from None


# ------------------------------------------------------------------- running
_STORE_LOCKS: dict[str, threading.Lock] = {}
_STORE_LOCKS_GUARD = threading.Lock()


def _store_lock(store: Path) -> threading.Lock:
    """The lock of one sweep store in this process: studies that run side by side on threads
    (:func:`undulate.reproduce.reproduce`) and share a store (``OUT/.sweeps/_shared``, ``_lone``) take
    turns, so the second reuses what the first computed instead of computing it again beside it."""
    key = str(Path(store).resolve())
    with _STORE_LOCKS_GUARD:
        return _STORE_LOCKS.setdefault(key, threading.Lock())


class StudyContext:
    """What a study's ``dataset`` step gets: cached sweeps and shared quantities.

    Everything it runs is recorded (identity, runs computed and reused,
    failures, wall time) for the study's JSON.
    """

    def __init__(self, config: StudyConfig, name: str, progress: bool = True):
        self.config = config
        self.name = name
        self.progress = progress
        self.sweeps: list[dict[str, Any]] = []
        self.failures: list[str] = []
        self._local = threading.local()  # a thread of :meth:`together`: its sweeps' records, kept apart
        self._verdicts: dict[tuple[str, str], str] | None = None
        self.parts: PartPlans | None = None
        """The plan each part of the study's runs follows at this look (:func:`part_plans`), set by the
        staging engine before each call of the study's ``dataset``; None outside a staged run (every
        part on the plan given)."""

    @property
    def seed(self) -> int:
        """The root seed of every random draw of the study (:attr:`StudyConfig.seed`)."""
        return self.config.seed

    def plan_for(self, part: str, plan: Any) -> Any:
        """The plan that ``part`` of the study's runs follows when ``dataset`` is handed ``plan``:
        ``plan`` itself while a claim or needed explanation reading the part is open; the plan of the
        look that made them all final once they are (its runs are made, and a final claim is never
        reopened: more runs would buy nothing); None for a part that only explanations nobody needs
        read (run nothing for it).  ``part`` is a name in some :attr:`Claim.reads` or
        :attr:`Explanation.reads` of the study (else UndulateError)."""
        if self.parts is None:
            return plan
        if part not in self.parts.declared:
            raise UndulateError(f"study {self.name!r}: no claim or explanation reads plan part {part!r} "
                                f"(declared: {', '.join(sorted(self.parts.declared)) or 'none'})")
        if part in self.parts.not_run:
            return None
        return self.parts.plans[part] if part in self.parts.plans else plan

    def needs_explanation(self, study: str, claim: str) -> bool:
        """Whether an explanation of ``study``'s ``claim`` can change its verdict: True when that claim
        fails in this output folder (``OUT/STUDY.json``), or when its verdict is not known there (the
        explaining study run on its own).  A claim that holds, is undecided or has no result cannot be
        ``explained`` (:mod:`undulate.claims`), so its explanation is moot: an explaining study need not
        run for it, and it never keeps a study's stages going."""
        if self._verdicts is None:  # read once: the other studies' files do not change during this one
            self._verdicts = _claim_verdicts(Path(self.config.out_dir), self.config)
        verdict = self._verdicts.get((study, claim))
        return verdict is None or verdict == FAILS

    def sweep_dir(self, part: str, folder: str | None = None) -> Path:
        """The store of sweep ``part``: ``OUT/.sweeps/FOLDER/PART-{quick|full}-seedS`` (``FOLDER``: the
        study's name unless given)."""
        return (Path(self.config.out_dir) / ".sweeps" / (folder or self.name)
                / f"{part}-{self.config.mode}-seed{self.config.seed}{_backend_suffix(self.config.execution)}")

    def shared_sweep(self, part: str, fn: Callable, grid: Grid, *, batched: bool | None = None) -> xr.Dataset:
        """:meth:`sweep` in the store every study of this output folder shares,
        ``OUT/.sweeps/_shared/PART-{quick|full}-seedS``: for the sweeps defined once in
        :mod:`._shared` and run by more than one study (computed by the first, reused by the
        others while their identity is the same)."""
        return self.sweep(part, fn, grid, where=self.sweep_dir(part, "_shared"), batched=batched)

    def sweep(self, part: str, fn: Callable, grid: Grid, *, where: Path | None = None,
              batched: bool | None = None) -> xr.Dataset:
        """Run ``fn`` over ``grid`` (resumable; recomputed if its code or arguments changed).
        ``batched``: ``fn(points, seeds) -> list[Dataset]`` runs a task's points at once; None (the
        default) reads it from ``fn``'s mark (:func:`undulate.sweep.batched_sweep_function`,
        :func:`undulate.sweep.run_sweep`).

        Returns the merged Dataset (dims ``grid.dims + ("replicate",)``; failed
        runs NaN and flagged ``run_failed``; they are listed in the study's
        JSON, not raised).
        """
        from ..sweep import run_sweep, warm_pool_running

        out = where or self.sweep_dir(part)
        ex = self.config.execution
        if runs_here(grid.n_runs, warm_pool_running(), ex):  # a few runs: here (undulate.execution.SERIAL_BELOW)
            ex = ex.replace(workers=1)
        with _store_lock(out):  # studies run side by side share stores (_shared, _lone): one sweep at a time
            res: SweepResult = run_sweep(fn, grid, out, progress=self.progress, batched=batched, execution=ex)
        try:
            rel = str(out.relative_to(self.config.out_dir))
        except ValueError:
            rel = str(out)
        sweeps, failures = self._records()
        sweeps.append({"part": part, "store": rel, **res.identity, "n_runs": res.n_runs,
                       "n_computed": res.n_computed, "n_reused": res.n_reused, "stale": res.stale,
                       "elapsed_s": res.elapsed_s, "n_failed": len(res.failures), "timing": res.timing})
        failures += [f"{part}: {f}" for f in res.failures]
        return res.dataset

    def _records(self) -> tuple[list[dict[str, Any]], list[str]]:
        """Where this thread's sweeps and failures are recorded: the study's lists, or in a thread of
        :meth:`together` that thread's own (added to its caller's in the calls' order)."""
        return getattr(self._local, "records", None) or (self.sweeps, self.failures)

    def together(self, *calls: Callable[[], Any]) -> list[Any]:
        """``[call() for call in calls]``, for calls that do not depend on each other (each runs its own
        sweeps).  Where the study runs wide (:func:`undulate.execution.runs_wide`: the Warp backend, or
        many local workers) they
        run side by side on threads, so their runs reach the device or the worker pool at once: a
        study's chain of sequential steps is then its longest call's, not the sum of them (a device
        step costs about the same for one world as for hundreds; a stage of 10-20 runs leaves most of
        16 workers idle).  Their sweeps and failures are recorded in the calls' order, and the first
        call (in that order) that raised raises here once all have ended.  Otherwise (a few cores,
        already kept busy) they run one after another, as written.  Results never depend on it
        (content-keyed stores; a store shared by two calls is computed once)."""
        if len(calls) < 2 or not runs_wide(self.config.execution):
            return [call() for call in calls]
        import contextvars
        from concurrent.futures import ThreadPoolExecutor

        def run(call: Callable[[], Any]) -> tuple[Any, BaseException | None, tuple[list, list]]:
            self._local.records = records = ([], [])
            try:
                return call(), None, records
            except BaseException as e:  # noqa: BLE001 - raised below, in the calls' order
                return None, e, records
            finally:
                self._local.records = None

        with ThreadPoolExecutor(len(calls), thread_name_prefix=f"undulate-{self.name}") as pool:
            # each call in a copy of this context: the study's physics meter counts its runs
            done = [f.result() for f in [pool.submit(contextvars.copy_context().run, run, c) for c in calls]]
        sweeps, failures = self._records()
        for _, _, (s, f) in done:
            sweeps += s
            failures += f
        for _, error, _ in done:
            if error is not None:
                raise error
        return [result for result, _, _ in done]

    def lone_swimmer(self, *, amplitude_rad: float | None = None, waves_per_body: float = 1.0,
                     n_links: int = 3, ground: str = "viscous", heading_guide: bool = False) -> xr.Dataset:
        """The free swimmer of one gait and ground (:func:`._runners.lone_swimmer`): its
        amplitude ``amplitude_m`` (the one definition of A), ``mean_joint_error_rad``,
        ``speed_m_s``, ``x_period_m``.  Measured once per gait and ground and shared by
        every study in ``OUT`` (store ``OUT/.sweeps/_lone/KEY``).  ``heading_guide``:
        :attr:`~undulate.params.Scene.heading_guide` (the yaw recoil removed)."""
        from ..params import Gait
        from ..sweep import Grid
        from ._runners import lone_swimmer

        beta = Gait().amplitude_rad if amplitude_rad is None else float(amplitude_rad)
        point = {"amplitude_rad": beta, "waves_per_body": float(waves_per_body), "n_links": int(n_links),
                 "ground": str(ground)}
        key = f"{ground}-N{int(n_links)}-xi{float(waves_per_body):g}-beta{beta:.9f}"
        if heading_guide:  # Scene.heading_guide (the yaw recoil removed)
            point["heading_guide"] = True
            key += "-headingguide"
        out = Path(self.config.out_dir) / ".sweeps" / "_lone" / (key + _backend_suffix(self.config.execution))
        ds = self.sweep(f"lone {key}", lone_swimmer, Grid(points=[point], seed=0), where=out)
        if bool(ds["run_failed"].any()):
            raise UndulateError(f"study {self.name!r}: the free swimmer {key} failed: {self._records()[1][-1]}")
        return ds.isel(point=0, replicate=0)


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


def _backend_suffix(execution: Execution) -> str:
    """``""`` for the MuJoCo backend, ``"-warp-DEVICE"`` for Warp: the two backends' stores live
    side by side in one output folder (their runs are never served for each other)."""
    return "" if execution.backend == "mujoco" else f"-{execution.backend}-{execution.device or 'default'}"


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


def identity(name: str, config: StudyConfig) -> dict[str, Any]:
    """What a study's files depend on besides its sweeps: mode, seed, package version and
    the hash of the study module's code (and every undulate module it imports); for a study that
    explains other studies' claims, also their verdicts in ``config.out_dir`` (it runs only for the
    claims that fail: :meth:`StudyContext.needs_explanation`)."""
    from .._source import code_hash
    from ..provenance import package_version
    from ..sweep import backend_identity

    info = describe(name)
    ident = {"study": name, "quick": bool(config.quick), "seed": int(config.seed),
             "undulate_version": package_version("undulate"), "code": code_hash(info.dataset, config.execution),
             "backend": backend_identity(config.execution)}
    if info.explanations:  # which explanations it runs for depends on the verdicts it explains
        known = _claim_verdicts(Path(config.out_dir), config)
        ident["explains"] = [list(t) for t in sorted({(e.study, e.claim, known.get((e.study, e.claim), "unknown"))
                                                      for e in info.explanations})]
    return ident


def is_current(name: str, config: StudyConfig) -> bool:
    """True when ``OUT/NAME.json`` was written by this code with these settings."""
    p = Path(config.out_dir) / f"{name}.json"
    try:
        doc = json.loads(p.read_text())
    except (OSError, ValueError):
        return False
    return doc.get("identity") == identity(name, config)


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
              workers: int | None = None, execution: Execution | None = None) -> Path:
    """Run study ``name`` and write its files into ``out_dir`` (created if needed).

    Returns ``out_dir/NAME.nc``; beside it ``NAME.png``, ``NAME.pdf`` and
    ``NAME.json``, each whole or not at all.  Sweeps finished earlier by the
    same code and arguments are reused; anything else is computed.  An
    unknown ``name`` raises :class:`~undulate.errors.ParameterError`.
    ``workers``: local worker processes (default: every core this process may
    use), kept warm across the study's sweeps (:func:`undulate.sweep.warm_workers`).
    ``execution``: how its runs are executed (:class:`undulate.execution.Execution`, which then holds
    the workers and scheduler; default: the settings in effect with ``workers`` and ``scheduler``).
    Another process writing to ``out_dir`` (a reproduction or a study) is a ParameterError before
    anything is written (:func:`undulate._outdir.writing_to`).
    """
    info = describe(name)
    config = StudyConfig(out_dir=out_dir, quick=quick, scheduler=scheduler, seed=seed,
                         workers=workers, execution=execution)
    _flag("progress", progress)
    out = config.out_dir
    from .._outdir import writing_to
    from ..sweep import warm_workers

    with writing_to(out, "out_dir"), warm_workers(config.workers), using(config.execution):
        return _run_study(info, name, config, out, progress)


def run_ahead(name: str, out_dir: str | os.PathLike, quick: bool = False, scheduler: str | None = None,
              seed: int = 0, workers: int | None = None, execution: Execution | None = None) -> dict[str, Any]:
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
                         workers=workers, execution=execution)
    config.out_dir.mkdir(parents=True, exist_ok=True)
    ctx = StudyContext(config, name, progress=False)
    ctx.needs_explanation = lambda study, claim: True  # the verdicts are not known yet: every one
    t0 = time.perf_counter()
    plans = stage_plans(info, config.quick)
    ctx.parts = part_plans(info, plans, {}, {}, ctx.needs_explanation)
    with using(config.execution):
        info.dataset(ctx, plans[-1] if _prefetching(config.execution) else plans[0])
    return {"n_runs": sum(s["n_runs"] for s in ctx.sweeps), "n_computed": sum(s["n_computed"] for s in ctx.sweeps),
            "wall_s": time.perf_counter() - t0}


STAGED = "undulate.staged"
"""The field metadata key of a plan's staged grid (:func:`staged`)."""


def staged(refine: int = 1) -> Any:
    """A field of a plan (a frozen dataclass) whose grid the study's looks grow: each look runs the grid
    thinned by index by the mode's strides (:data:`._stages.QUICK_STRIDES`, :data:`._stages.FULL_STRIDES`;
    every look's values a subset of the next's, so runs are reused), the last look all of it.
    ``refine`` > 1: a grid refined that many times from a coarser one (:func:`._analysis.refined`): its
    looks are the coarse grid's looks (strides times ``refine``), then the whole refined grid, one look
    more.  Every staged field of a plan has the same number of looks; a plan without one runs in one look."""
    if isinstance(refine, bool) or not isinstance(refine, int) or refine < 1:
        raise ParameterError("refine", "an integer >= 1", refine)
    return field(metadata={STAGED: refine})


def plan_looks(plan: Any, quick: bool) -> tuple[Any, ...]:
    """The looks of ``plan`` (:func:`staged`): ``plan`` with each staged field thinned, one plan a look,
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


def stage_plans(info: Study, quick: bool) -> tuple[Any, ...]:
    """The plans of ``info``'s looks in this mode: its declared :attr:`Study.stages`, else those of its
    plan's staged fields (:func:`plan_looks`; one, ``plan(quick)``, if none)."""
    plans = tuple(info.stages(quick)) if info.stages is not None else plan_looks(info.plan(quick), quick)
    if not plans:
        raise UndulateError(f"study {info.name!r} declares no stages")
    return plans


def _open(claims: list[dict[str, Any]], explanations: list[dict[str, Any]], growth_left: float,
          futile: Collection[str] = ()) -> list[str]:
    """What another stage may still decide after a look: undecided claims, except those whose interval
    would need more than ``growth_left`` times the runs it rests on to be decided at the last look's level
    (:func:`undulate.stats.runs_needed`; quick mode's cap cannot decide them:
    a futility stop, which never turns a claim into ``holds`` or ``fails``) and those an earlier look
    found futile (``futile``: their runs stay where they were, :func:`part_plans`);
    claims with ``no result`` (too few design points or runs with a result for an interval: more runs
    may give one); and explanations whose claim fails (the others are moot:
    :meth:`StudyContext.needs_explanation`)."""
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


def _claim_verdicts(out_dir: Path, config: StudyConfig) -> dict[tuple[str, str], str]:
    """``(study, claim) -> verdict`` of every study JSON in ``out_dir`` made in ``config``'s mode and seed."""
    out: dict[tuple[str, str], str] = {}
    for p in sorted(Path(out_dir).glob("*.json")):
        try:
            doc = json.loads(p.read_text())
        except (OSError, ValueError):
            continue
        if not isinstance(doc, dict) or not isinstance(doc.get("claims"), list):
            continue
        cfg = doc.get("config") or {}
        if bool(cfg.get("quick")) != bool(config.quick) or int(cfg.get("seed", 0)) != int(config.seed):
            continue
        for c in doc["claims"]:
            out[(str(c.get("study")), str(c.get("claim")))] = str(c.get("verdict"))
    return out


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
    ctx = StudyContext(config, name, progress=progress)
    engines = _engine_note(name, config.execution, progress)
    plans = stage_plans(info, config.quick)
    levels = stats.look_levels(len(plans))
    looks: list[dict[str, Any]] = []
    decided_claims: dict[Any, dict[str, Any]] = {}
    decided_explanations: dict[Any, dict[str, Any]] = {}
    futile_at: dict[str, int] = {}
    final_claims: dict[str, int] = {}
    final_explanations: dict[tuple[str, str], int] = {}
    with _walltime.meter() as here:  # what this process simulates (serial sweeps, direct runs)
        ctx.parts = part_plans(info, plans, {}, {}, ctx.needs_explanation)
        prefetched = _prefetch(info, ctx, plans)
        for k, (plan, level) in enumerate(zip(plans, levels), start=1):
            first = len(ctx.sweeps)
            ctx.parts = part_plans(info, plans, final_claims, final_explanations, ctx.needs_explanation)
            with stats.at_level(level, plan_at=levels[-1]):  # runs needed: to decide at the cap's look
                ds = info.dataset(ctx, plan)
                summary = info.summary(ds)
                claims = [{**c, "reference": info.reference} for c in judge(name, info.claims, summary)]
                explanations = [{**e, "needed": ctx.needs_explanation(e["study"], e["claim"])}
                                for e in explain(name, info.explanations, summary)]
            verdicts = {c["claim"]: c["verdict"] for c in claims}  # this look's own
            at = {"stage": k, "of": len(plans), "confidence_level": level}
            claims = _keep_decided(claims, decided_claims, lambda c: c["claim"],
                                   lambda c: c["verdict"] if c["verdict"] in (HOLDS, FAILS) else None, at)
            explanations = _keep_decided(explanations, decided_explanations, lambda e: (e["study"], e["claim"]),
                                         lambda e: e["shown"], at)
            still = _open(claims, explanations, _growth_left(len(plans), k, config.quick), futile_at)
            for c in claims:  # futile from here on: its runs stay on this look's plan
                if c["verdict"] == UNDECIDED and c["claim"] not in still:
                    futile_at.setdefault(c["claim"], k)
            # final: decided, or futile (from the look that found it so: its runs stopped there)
            final_claims = {**{key: c["decided_at"]["stage"] for key, c in decided_claims.items()}, **futile_at}
            final_explanations = {key: e["decided_at"]["stage"] for key, e in decided_explanations.items()}
            mine = ctx.sweeps[first:]
            parts = ctx.parts
            looks.append({**at, "n_runs": sum(s["n_runs"] for s in mine),
                          "n_computed": sum(s["n_computed"] for s in mine),
                          "verdicts": verdicts, "undecided": still,
                          "futile": [c["claim"] for c in claims
                                     if c["verdict"] == UNDECIDED and c["claim"] not in still],
                          "frozen_parts": dict(sorted(parts.frozen_at.items())),
                          "parts_not_run": sorted(parts.not_run)})
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
