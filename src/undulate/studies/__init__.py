"""Paper studies, one module each, registered by name.

>>> from undulate import studies
>>> studies.names()                                   # doctest: +SKIP
['pairs', 'compatibility', ...]
>>> studies.run_study("pairs", "results/", quick=True)   # doctest: +SKIP
PosixPath('results/pairs.nc')

A new study: copy the shape of ``pairs.py`` (``plan``, ``dataset``,
``summary``, ``CLAIMS``, ``figure``, then ``register(Study(...))``) and
append the module's name to :data:`STUDY_MODULES` (README: "Add a study").
"""

from ._registry import (
    STUDY_MODULES,
    Claim,
    Explanation,
    Study,
    StudyConfig,
    StudyContext,
    StudyInfo,
    Verdict,
    describe,
    identity,
    is_current,
    names,
    register,
    run_study,
)

__all__ = [
    "STUDY_MODULES",
    "Claim",
    "Explanation",
    "Study",
    "StudyConfig",
    "StudyContext",
    "StudyInfo",
    "Verdict",
    "describe",
    "identity",
    "is_current",
    "names",
    "register",
    "run_study",
]
