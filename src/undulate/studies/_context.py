"""What a study's ``dataset`` step gets besides its plan: :class:`StudyContext` (cached sweeps, shared
quantities, the plan each part follows), and the configuration of the run (:class:`StudyConfig`).

The context runs and caches the sweeps a study asks for (``ctx.sweep``; one store layout
``OUT/.sweeps/STUDY/PART-{quick|full}-seedS``), measures the shared quantities once
(``ctx.lone_swimmer``: one free swimmer per gait and ground, one definition of the amplitude A, stored
in ``OUT/.sweeps/_lone``) and records what it ran (identity, runs computed and reused, failures, wall
time) for the study's JSON.
"""

from __future__ import annotations

import json
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import ParameterError, UndulateError
from ..execution import Execution, runs_here, runs_wide, settings
from ..params import _flag
from ._protocol import FAILS

if TYPE_CHECKING:  # heavy imports stay lazy
    import xarray as xr

    from ..sweep import Grid, SweepResult
    from ._staging import PartPlans

__all__ = ["StudyConfig", "StudyContext"]


def _max_looks(value: Any) -> int | None:
    """``value`` as a cap on a study's looks: None (every look) or an integer >= 1."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ParameterError("max_looks", "an integer >= 1 (or none: every look)", value)
    return int(value)


@dataclass(frozen=True)
class StudyConfig:
    """How to run a study.

    ``out_dir``: where the study's files go (and its resumable sweep stores);
    ``quick``: the reduced plan that runs in minutes; ``scheduler``: a Dask
    scheduler address, or None for local processes; ``seed``: the root seed
    of every random draw; ``max_looks``: stop after at most this many of the study's looks (None: every
    look while a claim is undecided; a cap takes fewer runs and leaves more verdicts undecided, each
    judged at the level of a plan of that many looks); ``workers``: local worker processes (None: every
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
    max_looks: int | None = None

    def __post_init__(self):
        if isinstance(self.out_dir, bytes) or not isinstance(self.out_dir, str | os.PathLike):
            raise ParameterError("out_dir", "a folder's path (a str or os.PathLike)", type(self.out_dir).__name__)
        object.__setattr__(self, "out_dir", Path(self.out_dir))
        object.__setattr__(self, "quick", _flag("quick", self.quick))
        s = self.seed
        if isinstance(s, bool) or not isinstance(s, int | np.integer) or s < 0:
            raise ParameterError("seed", "an integer >= 0", s)
        object.__setattr__(self, "seed", int(s))
        object.__setattr__(self, "max_looks", _max_looks(self.max_looks))
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
        (the engine is in its identity, :func:`~._registry.identity`) and its cap on looks."""
        return {"out_dir": str(self.out_dir), "quick": self.quick, "scheduler": self.scheduler, "seed": self.seed,
                "workers": self.workers, "max_looks": self.max_looks}

    @property
    def mode(self) -> str:
        return "quick" if self.quick else "full"


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

    def __init__(self, config: StudyConfig, name: str, progress: bool = True,
                 explanations: tuple | None = None):
        self.config = config
        self.explanations = explanations
        """The study's :attr:`~._protocol.Study.explanations` (the staging engine passes them): which of them
        are findings (:meth:`needs_explanation`); None: every explanation counts as one proper."""
        self.name = name
        self.progress = progress
        self.sweeps: list[dict[str, Any]] = []
        self.failures: list[str] = []
        self._local = threading.local()  # a thread of :meth:`together`: its sweeps' records, kept apart
        self._verdicts: dict[tuple[str, str], str] | None = None
        self.parts: PartPlans | None = None
        """The plan each part of the study's runs follows at this look (:func:`~._staging.part_plans`), set by the
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
        read (run nothing for it).  ``part`` is a name in some :attr:`~._protocol.Claim.reads` or
        :attr:`~._protocol.Explanation.reads` of the study (else UndulateError)."""
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
        run for it, and it never keeps a study's stages going.  In quick mode only an explanation can be
        needed, not a finding (:class:`~._explanations.CaseFinding`): a finding never changes a verdict, so
        quick mode, which runs what decides the verdicts, leaves the runs that only findings read to full
        mode (their rows read "not run")."""
        if not self.may_run_for(study, claim):
            return False
        if self._verdicts is None:  # read once: the other studies' files do not change during this one
            self._verdicts = _claim_verdicts(Path(self.config.out_dir), self.config)
        verdict = self._verdicts.get((study, claim))
        return verdict is None or verdict == FAILS

    def may_run_for(self, study: str, claim: str) -> bool:
        """Whether this mode runs anything for ``study``'s ``claim`` whatever its verdict: in full mode
        always, in quick mode when this study has an explanation of it that is not a finding (always when
        its explanations were not given: an ad hoc context decides for itself)."""
        if not self.config.quick or self.explanations is None:
            return True
        return any((e.study, e.claim) == (study, claim) and not getattr(e, "finding", False)
                   for e in self.explanations)

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


def _backend_suffix(execution: Execution) -> str:
    """``""`` for the MuJoCo backend, ``"-warp-DEVICE"`` for Warp: the two backends' stores live
    side by side in one output folder (their runs are never served for each other)."""
    return "" if execution.backend == "mujoco" else f"-{execution.backend}-{execution.device or 'default'}"


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
