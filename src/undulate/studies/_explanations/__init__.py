"""The sensitivity study's explanations of failing claims: one module per cause.

Every module here defines ``EXPLANATIONS``, a tuple of
:class:`~._protocol.CaseExplanation` (the protocol: :mod:`._protocol`), which
reads the sensitivity study's results by typed case id
(:class:`~undulate.studies._sensitivity_design.CaseId`).  To add one: write a
module with its case ids, its ``judge`` and its ``EXPLANATIONS``, and add it
to :data:`MODULES`; the tests check that every module is listed and names only
cases the study makes.
"""

from __future__ import annotations

from . import confinement, groups, impulse, links, swimming, xi32
from ._protocol import CaseExplanation, CaseFinding, CaseResults, results_by_case

__all__ = ["EXPLANATIONS", "MODULES", "CaseExplanation", "CaseFinding", "CaseResults", "results_by_case"]

MODULES = (impulse, swimming, groups, xi32, links, confinement)
"""The explanation modules, in the order their explanations are judged and saved."""

EXPLANATIONS: tuple[CaseExplanation, ...] = tuple(e for m in MODULES for e in m.EXPLANATIONS)
