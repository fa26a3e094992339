"""The study protocol: what a study states, and the types of its judgements.

A study module states, in this order (read ``pairs.py`` as the example; docs/guide/studies.md)::

    plan(quick) -> Plan                    # its grids and constants, quick and full; staged() grids grow by look
    dataset(ctx, plan) -> xarray.Dataset   # runs its sweeps through ctx, assembles the data
    summary(ds) -> dict                    # PURE: numbers (with uncertainties) from the data
    CLAIMS = (Claim(...), ...)             # PURE functions of the summary -> Verdict; reads: the plan parts
    figure(ds) -> Figure

and registers them with ``register(Study(name=..., plan=plan, dataset=...,
summary=summary, claims=CLAIMS, figure=figure))`` (:mod:`._registry`).  Adding the module under
``undulate/studies/`` is the only step: the registry imports every public module of the package.
Studies are listed and reproduced in the order of their :attr:`Study.order` (by default the paper's
figure number; see there).  A study knows nothing of how it is run: the staging engine
(:mod:`._staging`) runs it in looks, hands its ``dataset`` the plan of each part
(:meth:`._context.StudyContext.plan_for`), judges its claims and writes its files.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from .. import stats
from ..errors import ParameterError, UndulateError

if TYPE_CHECKING:  # heavy imports stay lazy
    import xarray as xr
    from matplotlib.figure import Figure

    from ._context import StudyContext

__all__ = ["Claim", "SupersededCriterion", "Verdict", "Explanation", "Study", "judge", "explain", "VERDICTS", "HOLDS",
           "FAILS", "UNDECIDED", "NO_RESULT", "EXPLAINED", "staged"]

HOLDS, FAILS, UNDECIDED, NO_RESULT = "holds", "fails", "undecided", "no result"


VERDICTS = (HOLDS, FAILS, UNDECIDED, NO_RESULT)
"""A study's verdicts on a claim: its intervals lie inside the accepted region (``holds``), one lies
wholly outside (``fails``), none is outside and one straddles a boundary (``undecided``), or there is no
number to judge (``no result``)."""


EXPLAINED = "explained"
"""Not a study's verdict: :mod:`undulate.claims` turns a claim that ``fails`` into
``explained`` when some study's :class:`Explanation` of it was shown by that study's runs."""


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
    e.g. ``("xi=1",)``; asked for with :meth:`~._context.StudyContext.plan_for`).  Once every claim and needed
    explanation reading a part is final, the staging engine keeps that part's runs on the plan of the
    look that made them final (:func:`~._staging.part_plans`).  Empty: the claim reads no part a look may freeze."""

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
    is unknown: :meth:`~._context.StudyContext.needs_explanation`); else the study is handed None for it."""

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
    explanations is undecided (:func:`~._staging.run_study`).  None (the default, and all a new study needs): the
    looks of its plan's :func:`staged` fields (:func:`~._staging.plan_looks`), or one stage, ``plan(quick)``."""
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
