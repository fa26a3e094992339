import os

os.environ.setdefault("MPLBACKEND", "Agg")


import pytest  # noqa: E402


@pytest.fixture(scope="module")
def whole_plans():
    """Every registered study runs its mode's whole plan in one look (``Study.stages`` off), for a
    whole test module (its module-scoped runs included): for the tests that check the physics a plan
    measures (its grid sizes, its fits), not the staging (tests/test_staged_verdicts.py)."""
    import dataclasses

    from undulate.studies import _registry

    _registry._load()
    with pytest.MonkeyPatch.context() as mp:
        for name, info in list(_registry._REGISTRY.items()):
            mp.setitem(_registry._REGISTRY, name, dataclasses.replace(info, stages=None))
        yield
