import os
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")


import pytest  # noqa: E402

from alone_lock import beside_others  # noqa: E402


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """On a pytest-xdist worker, each test (its fixtures' setup and teardown included) holds the
    workers' shared lock, and a test marked ``alone`` holds it exclusively (``alone_lock``)."""
    if not hasattr(item.config, "workerinput"):  # one process: nothing runs beside a test
        yield
        return
    with beside_others(Path(item.config.option.basetemp).parent, item.get_closest_marker("alone") is not None):
        yield


@pytest.fixture(autouse=True)
def _fresh_models():
    """Every test compiles its own models: compile_scene's per-process model cache starts empty (a
    test that patches the model builder must not hand its models to the next)."""
    from undulate.simulation._compile import clear_model_cache

    clear_model_cache()
    yield


@pytest.fixture(scope="module")
def whole_plans():
    """Every registered study runs its mode's whole plan in one look (``Study.stages`` one plan), for a
    whole test module (its module-scoped runs included): for the tests that check the physics a plan
    measures (its grid sizes, its fits), not the staging (tests/test_staged_verdicts.py)."""
    import dataclasses

    from undulate.studies import _registry

    _registry._load()
    with pytest.MonkeyPatch.context() as mp:
        for name, info in list(_registry._REGISTRY.items()):
            mp.setitem(_registry._REGISTRY, name,
                       dataclasses.replace(info, stages=lambda quick, info=info: (info.plan(quick),)))
        yield


@pytest.fixture(scope="session")
def benchmark_script():
    """``benchmark_script("bench_NAME")``: the script ``benchmarks/bench_NAME.py`` as a module (the
    benchmarks are scripts, not a package), loaded once a session, for tests of their own logic."""
    import importlib.util
    from pathlib import Path

    loaded: dict = {}

    def load(name: str):
        if name not in loaded:
            path = Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
            spec = importlib.util.spec_from_file_location(name, path)
            loaded[name] = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(loaded[name])
        return loaded[name]

    return load


@pytest.fixture(scope="module")
def warm_pool():
    """One warm pool of worker processes for a whole test module's sweeps, as ``run_study`` and
    ``reproduce`` keep one for a whole study or reproduction (:func:`undulate.sweep.warm_workers`):
    for modules that run studies' sweeps through their ``dataset`` directly, where each sweep would
    otherwise start its processes again (~1.5 s of imports each).  Not for tests of the pools
    themselves, nor for a module that changes the environment or the code its workers import."""
    from undulate.sweep import warm_workers

    with warm_workers():
        yield
