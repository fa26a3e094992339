"""Paper studies, one module each, registered by name.

>>> from undulate import studies
>>> studies.names()                                   # doctest: +SKIP
['compatibility', ...]
>>> studies.run_study("compatibility", "results/")    # doctest: +SKIP
PosixPath('results/compatibility.nc')

A new study: add a module here that decorates ``run(config) -> StudyResult``
with :func:`register`, and append its module name to :data:`STUDY_MODULES`.
"""

from ._registry import (
    STUDY_MODULES,
    StudyConfig,
    StudyInfo,
    StudyResult,
    describe,
    names,
    register,
    run_study,
)

__all__ = [
    "STUDY_MODULES",
    "StudyConfig",
    "StudyInfo",
    "StudyResult",
    "describe",
    "names",
    "register",
    "run_study",
]
