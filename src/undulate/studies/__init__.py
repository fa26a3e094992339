"""Paper studies, one module each, registered by name.

>>> from undulate import studies
>>> studies.names()                                   # doctest: +SKIP
['pairs', 'compatibility', ...]
>>> studies.run_study("pairs", "results/", quick=True)   # doctest: +SKIP
PosixPath('results/pairs.nc')

A new study: copy the shape of ``pairs.py`` (``plan``, ``dataset``,
``summary``, ``CLAIMS``, ``figure``, then ``register(Study(...))``; docs/guide/studies.md) in a new
module here; the registry imports every public module of this package, so there
is no list to edit (README: "Add a study").  The registry stages it: a study never sees looks,
devices or workers.  ``Study.order`` places it among the
others (default: its paper figure number).
"""

from ._context import StudyConfig, StudyContext
from ._protocol import Claim, Explanation, Study, SupersededCriterion, Verdict, staged
from ._registry import describe, identity, is_current, names, register
from ._staging import run_ahead, run_study

__all__ = [
    "Claim",
    "Explanation",
    "Study",
    "StudyConfig",
    "StudyContext",
    "SupersededCriterion",
    "Verdict",
    "describe",
    "identity",
    "is_current",
    "names",
    "register",
    "run_ahead",
    "run_study",
    "staged",
]
