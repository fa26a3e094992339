"""The protocol every explanation of the sensitivity study follows.

An explanation module (one per failing claim, or per family of claims with one
cause) defines ``EXPLANATIONS``: a tuple of :class:`CaseExplanation`, each
naming the claim it explains (``study``, ``claim``: that study's exact
``Claim.claim`` text), its ``cause`` in words, the :class:`CaseId` s of the
sensitivity study's ``cases`` it reads, and ``judge``: a pure function of
:class:`CaseResults` (those cases' summary entries) returning ``(shown,
measured, value)``.  :class:`CaseExplanation` is an
:class:`~undulate.studies.Explanation`, so the registry and
:mod:`undulate.claims` use it unchanged; its ``check(summary)`` runs ``judge``
on the summary's results keyed by case id.

``shown`` is three-valued, like a claim's verdict: True only when every
condition the cause needs is decided in its favour, False when one is decided
against it, None otherwise (an interval a condition rests on straddles its
bound, or has no interval yet): combine conditions with :func:`all_of` and
:func:`negate`, and name each case's state in the text with :func:`state_word`.

Naming a case the sensitivity study never makes fails when the module is
imported, and reading an undeclared case fails when the check runs
(:class:`UnknownCaseError`); a declared case missing from a summary (a plan
without it) reads as None, and the judge reports the cause as not shown
(False: this plan has no runs that could show it).

A declared case among the summary's ``skipped_cases`` (its factor group was not
run because the claim it explains does not fail:
the staging engine hands the study None for a part no needed explanation reads) is no evidence either way:
the check then returns ``(None, NOT_RUN, None)`` without calling ``judge``.

**One change.**  An explanation a referee accepts is one change to the model,
chosen from the paper's text or from physics before the runs that show it,
that recovers the paper's behaviour under the claim's unchanged criterion,
with the mechanism shown.  Every :class:`CaseExplanation` names its
``changes`` (each in words, against the default model), and one that names
more than one is refused when its module is imported
(:class:`MultipleChangesError`).  Several changes together, or a yardstick
chosen after seeing the data, are a :class:`CaseFinding`: judged the same way
and listed beside the claim, which stays ``fails``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from ... import stats
from ...errors import UndulateError
from .._protocol import Explanation
from .._sensitivity_design import FACTOR_GROUPS, CaseId, CaseSet, UnknownCaseError, known_cases

__all__ = ["CaseExplanation", "CaseFinding", "CaseResults", "MultipleChangesError", "NOT_RUN", "Shown",
           "results_by_case", "all_of", "negate", "number", "state_word"]

NOT_RUN = ("not run: the claim it explains does not fail in this reproduction (or, in quick mode, only "
           "findings read these runs: full mode runs them)")
"""The measured text of an explanation whose cases the sensitivity study did not run (``skipped_cases``)."""

Shown = tuple[bool | None, str, Any]
"""What a check returns: whether the runs show the cause (True), refute it (False) or leave it undecided
(None), the evidence as text, and as numbers."""


all_of = stats.all_of
"""Three-valued AND of an explanation's conditions (:func:`undulate.stats.all_of`): False if one is decided
against the cause, else None if one is undecided (or has no number), else True."""


def negate(condition: bool | None) -> bool | None:
    """Three-valued NOT: "the criterion fails" from whether it holds (None stays None)."""
    return None if condition is None else not bool(condition)


def number(value: Any) -> float:
    """A summary number as a float; NaN where it is missing (None after a JSON round trip, NaN)."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def state_word(state: bool | None, verdict: str | None = None) -> str:
    """A criterion's state in words: its ``verdict`` when the summary gives one (``no result`` where a
    number is missing), else holds / fails / undecided."""
    if verdict:
        return verdict
    return "holds" if state is True else "fails" if state is False else "undecided"


def _entries(summary: dict[str, Any]) -> Iterator[dict[str, Any]]:
    """Every entry of ``summary`` that carries a ``case_id``: the pair cases, the group cases, the body
    widths (confinement) and the impulse rows per drag."""
    yield from summary.get("cases", {}).values()
    yield from summary.get("groups", {}).values()
    yield from summary.get("confinement", {}).values()
    yield from summary.get("impulse", {}).get("by_drag", [])


def results_by_case(summary: dict[str, Any]) -> dict[CaseId, dict[str, Any]]:
    """The summary's per-case entries keyed by their (parsed) ``case_id``; a duplicate id raises."""
    out: dict[CaseId, dict[str, Any]] = {}
    for e in _entries(summary):
        cid = CaseId.parse(e["case_id"])
        if cid in out:
            raise UnknownCaseError(f"case {cid} twice in one summary")
        out[cid] = e
    return out


class CaseResults:
    """The entries of the cases an explanation declares, keyed by :class:`CaseId` (read-only).

    :meth:`get` returns a case's summary entry (None where this summary has no result for it);
    :meth:`link_set` one set of the link-number cases (the summary's ``links_sets`` entry);
    ``summary`` is the whole summary, for study-wide numbers."""

    def __init__(self, summary: dict[str, Any], declared: Iterable[CaseId]):
        self.summary = summary
        self._declared = frozenset(declared)
        self._entries = results_by_case(summary)

    def _require(self, cid: CaseId) -> None:
        if cid not in self._declared:
            raise UnknownCaseError(f"case {cid} is not among the explanation's declared cases "
                                   f"({', '.join(sorted(map(str, self._declared)))})")

    def get(self, cid: CaseId) -> dict[str, Any] | None:
        """The summary entry of case ``cid`` (None if this summary has none); ``cid`` must be declared."""
        self._require(cid)
        return self._entries.get(cid)

    def link_set(self, case_set: CaseSet) -> dict[str, Any] | None:
        """The summary's ``links_sets`` entry of ``case_set`` (the link-number trend over its N; None if
        this summary has none); some case of that set must be declared."""
        mine = [c for c in self._declared if c.case_set is case_set]
        if not mine:
            raise UnknownCaseError(f"no case of set {case_set.value!r} among the explanation's declared cases")
        return self.summary.get("links_sets", {}).get(case_set.value)


class MultipleChangesError(UndulateError, ValueError):
    """An explanation that names other than exactly one change to the model (a :class:`CaseFinding` may
    name several)."""


@dataclass(frozen=True)
class CaseExplanation(Explanation):
    """An :class:`~undulate.studies.Explanation` judged on the sensitivity study's cases by id.

    Give ``study``, ``claim``, ``cause``, ``changes``, ``cases`` and ``judge`` (not ``check``: it is made
    here, ``check(summary) = judge(CaseResults(summary, cases))``).  Every id in ``cases`` must be one the
    study makes in quick or full mode (:func:`~undulate.studies._sensitivity_design.planned_cases`).
    ``changes``: the model changes against the default that the cause rests on, each in words (e.g.
    ``("N = 3 -> 8 links",)``): exactly one, or :class:`MultipleChangesError` (a :class:`CaseFinding`
    may name several).  Its ``reads`` are made here too: the factor groups its cases come from
    (:data:`~undulate.studies._sensitivity_design.FACTOR_GROUPS`)."""

    check: Callable[[dict[str, Any]], Shown] | None = field(default=None, repr=False, compare=False)
    cases: tuple[CaseId, ...] = ()
    judge: Callable[[CaseResults], Shown] | None = field(default=None, repr=False, compare=False)
    changes: tuple[str, ...] | None = None

    def __post_init__(self):
        if self.judge is None or self.check is not None:
            raise TypeError("CaseExplanation takes a judge (of CaseResults), not a check")
        if not self.cases:
            raise UnknownCaseError(f"the explanation of {self.claim!r} declares no cases")
        unknown = [str(c) for c in self.cases if c not in known_cases()]
        if unknown:
            raise UnknownCaseError(f"the explanation of {self.claim!r} names cases the sensitivity study does "
                                   f"not make: {', '.join(unknown)}")
        changes = self.changes
        if changes is None or isinstance(changes, str) or not all(isinstance(c, str) and c.strip() for c in changes):
            raise MultipleChangesError(f"the explanation of {self.claim!r} must name its changes to the model "
                                       f"(a tuple of non-empty texts), not {changes!r}")
        object.__setattr__(self, "changes", tuple(changes))
        if not self.finding and len(self.changes) != 1:
            raise MultipleChangesError(
                f"the explanation of {self.claim!r} names {len(self.changes)} changes to the model "
                f"({'; '.join(self.changes) or 'none'}): an explanation is one change that recovers the claim "
                "under its unchanged criterion; record several together as a CaseFinding (the claim stays fails)")
        object.__setattr__(self, "check", functools.partial(_check, self.judge, tuple(self.cases)))
        # the plan parts its cases come from (the sensitivity study's factor groups): run while it is needed
        object.__setattr__(self, "reads", tuple(dict.fromkeys(FACTOR_GROUPS[c.case_set] for c in self.cases
                                                              if c.case_set in FACTOR_GROUPS)))


@dataclass(frozen=True)
class CaseFinding(CaseExplanation):
    """A finding about a failing claim, judged like a :class:`CaseExplanation` on the sensitivity
    study's cases, that is not an explanation a referee accepts: several changes together (``changes``
    may name any number), or a yardstick chosen after seeing the data.  Shown or not, the claim stays
    ``fails`` and the finding is written beside it (:func:`undulate.claims.apply_explanations`)."""

    finding: bool = True

    def __post_init__(self):
        if not self.finding:
            raise MultipleChangesError(f"a CaseFinding of {self.claim!r} is a finding (finding=True)")
        super().__post_init__()


def skipped_cases(summary: dict[str, Any]) -> frozenset[CaseId]:
    """The cases the summary's study did not run (its ``skipped_cases``; none if absent)."""
    return frozenset(CaseId.parse(c) for c in summary.get("skipped_cases") or ())


def _check(judge: Callable[[CaseResults], Shown], cases: tuple[CaseId, ...], summary: dict[str, Any]) -> Shown:
    if skipped_cases(summary) & set(cases):  # not run: no evidence either way
        return None, NOT_RUN, None
    return judge(CaseResults(summary, cases))
