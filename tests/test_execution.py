"""The execution seam (:mod:`undulate.execution`): one frozen settings object, read from the environment
in one place, passed down to where runs execute; the policy of where runs go under public names; and a
run stepped on another engine than the one asked for says so in its Dataset."""

from __future__ import annotations

import ast
import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from undulate import execution
from undulate.errors import ParameterError
from undulate.execution import SETTINGS, Execution, current, using

SRC = Path(__file__).resolve().parents[1] / "src" / "undulate"
HERE = Path(__file__).resolve().parent
SEAM = "undulate.execution"


def _modules():
    """``(dotted name, package, path, tree)`` of every module of the package."""
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC.parent).with_suffix("")
        parts = list(rel.parts)
        is_package = parts[-1] == "__init__"
        if is_package:
            parts = parts[:-1]
        name = ".".join(parts)
        yield name, name if is_package else name.rpartition(".")[0], path, ast.parse(path.read_text())


def _environment_reads(tree: ast.AST) -> list[int]:
    """Lines that touch the process environment: ``os.environ``, ``getenv``, ``putenv``, ``unsetenv``, or
    such a name imported from ``os``."""
    lines = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and node.attr in ("environ", "environb", "getenv", "putenv", "unsetenv"):
            lines.append(node.lineno)
        elif isinstance(node, ast.ImportFrom) and node.module == "os" and any(
                a.name in ("environ", "environb", "getenv", "putenv", "unsetenv") for a in node.names):
            lines.append(node.lineno)
    return lines


def test_no_module_outside_the_seam_reads_the_environment():
    """Only :mod:`undulate.execution` touches ``os.environ`` (and ``getenv``): every setting has one place
    that reads it, documented there."""
    found = {name: _environment_reads(tree) for name, _, _, tree in _modules() if name != SEAM}
    assert {k: v for k, v in found.items() if v} == {}
    assert _environment_reads(ast.parse((SRC / "execution.py").read_text()))  # the scan sees the seam's own


def _imported(name: str, package: str, node: ast.AST) -> list[str]:
    """The dotted targets an import statement names (``from X import y`` gives ``X`` and ``X.y``)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    if isinstance(node, ast.ImportFrom):
        base = node.module or ""
        if node.level:
            up = package.split(".")
            up = up[: len(up) - (node.level - 1)]
            base = ".".join(up + ([node.module] if node.module else []))
        return [base] + [f"{base}.{a.name}" for a in node.names]
    return []


def _private_owner(target: str, packages: set[str], modules: set[str]) -> str | None:
    """The package a target's first underscore part is private to (None: no such part): the package
    that holds the underscore module or subpackage, or the package of the module that holds the
    underscore name."""
    parts = target.split(".")
    for i, part in enumerate(parts):
        if part.startswith("_") and not part.startswith("__"):
            holder = ".".join(parts[:i])
            return holder if holder in packages else holder.rpartition(".")[0] if holder in modules else holder
    return None


def _private_imports() -> list[tuple[str, int, str]]:
    mods = list(_modules())
    packages = {pkg for name, pkg, path, _ in mods if path.name == "__init__.py"}
    modules = {name for name, _, _, _ in mods}
    bad = []
    for name, package, _, tree in mods:
        for node in ast.walk(tree):
            for target in _imported(name, package, node):
                if not target.startswith("undulate"):
                    continue
                owner = _private_owner(target, packages, modules)
                if owner is not None and package != owner and not package.startswith(owner + "."):
                    bad.append((name, node.lineno, target))
    return sorted(set(bad))


def test_no_module_imports_another_packages_private_module():
    """A private (underscore) module or name is its package's: modules of that package and of its
    subpackages may import it, no other (``from ..sweep._executors import`` in ``undulate.studies`` is a
    violation; ``from .._io import`` there is not: ``_io`` is ``undulate``'s, which holds ``studies``)."""
    assert _private_imports() == []


def test_the_private_import_scan_finds_a_violation(tmp_path):
    """The scan's rule, on statements it must flag and must pass."""
    packages = {"undulate", "undulate.sweep", "undulate.studies", "undulate.simulation"}
    modules = packages | {"undulate.params", "undulate.sweep._executors", "undulate.simulation._record"}
    tree = ast.parse("from ..sweep._executors import default_workers\nfrom .._io import atomic_output\n"
                     "from ..simulation import _state_layout\nfrom ..params import _flag\n")
    flagged = []
    for node in tree.body:
        for target in _imported("undulate.studies.x", "undulate.studies", node):
            owner = _private_owner(target, packages, modules)
            if owner is not None and owner != "undulate.studies" and not "undulate.studies".startswith(owner + "."):
                flagged.append(node.lineno)
    assert sorted(set(flagged)) == [1, 3]


# ------------------------------------------------------------------ the settings
def test_settings_are_validated_naming_the_field():
    for kw, name in [(dict(backend="cuda"), "backend"), (dict(device="gpu", backend="warp"), "device"),
                     (dict(device="cpu"), "device"), (dict(workers=0), "workers"), (dict(workers=True), "workers"),
                     (dict(workers=2, scheduler="tcp://x:1"), "workers"), (dict(warp_processes=257), "warp_processes"),
                     (dict(lone_swimmers="gpu"), "lone_swimmers"), (dict(cores_up_to=-1), "cores_up_to"),
                     (dict(prefetch="yes"), "prefetch"), (dict(reduce_on_device=None), "reduce_on_device"),
                     (dict(steps_per_graph=1001), "steps_per_graph"), (dict(compile_workers=0), "compile_workers"),
                     (dict(streams=1), "streams"), (dict(timeline=""), "timeline"), (dict(stats_file=3), "stats_file")]:
        with pytest.raises(ParameterError) as err:
            Execution(**kw)
        assert err.value.name == name, kw
    ex = Execution(backend="warp", device="cpu", workers=2, cores_up_to=0, timeline=Path("/tmp/t.jsonl"))
    assert ex.timeline == "/tmp/t.jsonl"
    with pytest.raises(dataclasses.FrozenInstanceError):
        ex.backend = "mujoco"  # type: ignore[misc]


def test_every_setting_has_a_field_and_one_variable():
    fields = [f.name for f in dataclasses.fields(Execution)]
    assert [s.name for s in SETTINGS] == fields
    assert len({s.env for s in SETTINGS}) == len(SETTINGS)
    assert all(s.env.startswith("UNDULATE_") for s in SETTINGS)
    assert all(f"``{s.env}``" in execution.__doc__ for s in SETTINGS)  # the one place that reads them names them


def test_a_bad_variable_is_refused_naming_it():
    for var, value in [("UNDULATE_BACKEND", "gpu"), ("UNDULATE_WARP_PROCESSES", "0"), ("UNDULATE_WARP_PREFETCH", "yes"),
                       ("UNDULATE_WARP_CORES_UP_TO", "many"), ("UNDULATE_WORKERS", "-3"),
                       ("UNDULATE_WARP_LONE_SWIMMERS", "cpu")]:
        with pytest.raises(ParameterError, match=var):
            Execution.from_environment({var: value})
    assert Execution.from_environment({"UNDULATE_DEVICE": "cpu"}) == Execution()  # mujoco steps on the CPU
    assert Execution.from_environment({"UNDULATE_BACKEND": ""}) == Execution()  # empty: unset


def test_settings_travel_through_the_environment_to_another_process():
    """settings -> environment variables -> :meth:`Execution.from_environment` in a fresh process: the same
    settings (how a child process may rebuild them)."""
    ex = Execution(backend="warp", device="cpu", workers=3, warp_processes=2, lone_swimmers="mujoco", cores_up_to=0,
                   prefetch=True, reduce_on_device=False, deterministic=False, steps_per_graph=4,
                   compile_workers=1, streams=False, timeline="/tmp/timeline.jsonl", stats_file="/tmp/stats.jsonl")
    env = {k: v for k, v in os.environ.items() if not k.startswith("UNDULATE_")}
    env.update(ex.to_environment())
    assert set(ex.to_environment()) == {s.env for s in SETTINGS} - {"UNDULATE_SCHEDULER"}
    code = ("import dataclasses, json; from undulate.execution import Execution; "
            "print(json.dumps(dataclasses.asdict(Execution.from_environment())))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    assert Execution(**json.loads(out)) == ex
    assert Execution.from_environment(Execution().to_environment()) == Execution()  # defaults: no variables


def test_export_makes_the_settings_this_process_default(monkeypatch):
    for s in SETTINGS:
        monkeypatch.delenv(s.env, raising=False)
    ex = Execution(cores_up_to=5, streams=False)
    ex.export()
    assert current() == ex
    Execution().export()
    assert not any(s.env in os.environ for s in SETTINGS)


def test_using_passes_settings_down_and_ends_with_its_block(monkeypatch):
    monkeypatch.delenv("UNDULATE_WARP_CORES_UP_TO", raising=False)
    with using(Execution(cores_up_to=3)) as ex:
        assert current() is ex and execution.cores_up_to("cuda") == 3
        monkeypatch.setenv("UNDULATE_WARP_CORES_UP_TO", "9")  # the settings passed down win over the environment
        assert execution.cores_up_to("cuda") == 3
    assert execution.cores_up_to("cuda") == 9
    with pytest.raises(ParameterError, match="execution"):
        with using("warp"):  # type: ignore[arg-type]
            pass


def test_keywords_build_settings_and_refuse_to_double_them(monkeypatch):
    monkeypatch.delenv("UNDULATE_SCHEDULER", raising=False)
    monkeypatch.setenv("UNDULATE_WARP_CORES_UP_TO", "4")
    assert execution.settings(workers=2) == Execution(workers=2, cores_up_to=4)
    with pytest.raises(ParameterError, match="workers"):
        execution.settings(Execution(), workers=2)
    from undulate.studies import StudyConfig

    cfg = StudyConfig(out_dir=".", execution=Execution(workers=3))
    assert cfg.workers == 3 and cfg.execution.workers == 3
    assert StudyConfig(out_dir=".", workers=2).execution == Execution(workers=2, cores_up_to=4)


# ------------------------------------------------------------------ where runs go
def test_the_policy_of_where_runs_go():
    gpu, cpu = Execution(backend="warp", device="cuda"), Execution(backend="warp", device="cpu")
    assert execution.lone_swimmers_engine("cuda", gpu) == "mujoco" and execution.lone_swimmers_engine("cpu", cpu) == "warp"
    assert execution.cores_up_to("cuda", gpu) == execution.usable_cpus() and execution.cores_up_to("cpu", cpu) == 0
    assert execution.engine_for("warp", "cuda", n_swimmers=1, execution=gpu)[0] == "mujoco"
    assert execution.engine_for("warp", "cuda", n_scenes=10**5, execution=gpu) == ("warp", None)
    assert execution.engine_for("mujoco", None, n_swimmers=1, execution=gpu) == ("mujoco", None)
    assert execution.engine_for("warp", "cpu", n_swimmers=1, n_scenes=1, execution=cpu) == ("warp", None)
    assert execution.prefetch("cuda", gpu) and not execution.prefetch("cpu", cpu)
    assert not execution.prefetch("cuda", Execution()) and execution.prefetch("cpu", cpu.replace(prefetch=True))
    assert execution.prefetch(None, cpu.replace(prefetch=False)) is False
    with pytest.raises(ParameterError, match="device"):
        execution.prefetch(None, gpu)  # the rule needs the device
    assert execution.runs_wide(cpu) and not execution.runs_wide(Execution(workers=2))
    assert execution.runs_wide(Execution(workers=execution.WIDE_WORKERS))
    if _has_dask():
        assert not execution.runs_wide(Execution(scheduler="tcp://x:1"))  # the cluster's size is unknown here
    assert execution.studies_side_by_side(5, Execution(workers=2)) == execution.SIDE_BY_SIDE
    assert execution.studies_side_by_side(5, cpu) == 6  # every study and the animations
    assert execution.runs_here(execution.SERIAL_BELOW - 1, False, Execution())
    assert not execution.runs_here(2, True, Execution()) and execution.runs_here(1, True, Execution())
    assert not execution.runs_here(execution.SERIAL_BELOW, False, Execution())
    assert execution.substitution_note(Execution()) is None and execution.substitution_note(cpu, "cpu") is None
    assert "scenes of one swimmer" in execution.substitution_note(gpu, "cuda")


def _has_dask() -> bool:
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


def test_a_sweep_runs_under_the_settings_passed_down(tmp_path, monkeypatch):
    """``run_sweep(execution=...)``: the runs see those settings in this process and in a local pool's
    processes, whatever the environment says."""
    if str(HERE) not in sys.path:  # workers inherit sys.path, so they can import sweep_funcs
        monkeypatch.syspath_prepend(str(HERE))
    import sweep_funcs

    from undulate.sweep import Grid, run_sweep

    monkeypatch.setenv("UNDULATE_WARP_CORES_UP_TO", "9")
    grid = Grid(axes={"k": [0, 1, 2, 3]}, seed=0)
    here = run_sweep(sweep_funcs.execution_seen, grid, tmp_path / "here", progress=False,
                     execution=Execution(workers=1, cores_up_to=7))
    assert set(here.dataset["cores_up_to"].values.ravel()) == {7}
    pool = run_sweep(sweep_funcs.execution_seen, grid, tmp_path / "pool", progress=False,
                     execution=Execution(workers=2, cores_up_to=5))
    assert set(pool.dataset["cores_up_to"].values.ravel()) == {5}
    assert os.getpid() not in set(pool.dataset["pid"].values.ravel())  # they ran in other processes
    with pytest.raises(ParameterError, match="workers"):
        run_sweep(sweep_funcs.execution_seen, grid, tmp_path / "x", workers=2, execution=Execution())


# ------------------------------------------------------------------ a substituted engine is recorded
def test_every_run_records_the_engine_that_stepped_it():
    from undulate.params import Scene, SimOptions
    from undulate.simulation import simulate

    ds = simulate(Scene(phases_rad=(0.0,)), SimOptions(duration_s=0.1, sample_rate_hz=20.0, backend="mujoco"))
    assert (ds.attrs["engine"], ds.attrs["engine_requested"]) == ("mujoco", "mujoco")
    assert "engine_reason" not in ds.attrs


def test_a_run_sent_to_another_engine_says_so_in_its_dataset():
    """A lone swimmer asked of Warp, with ``lone_swimmers="mujoco"`` (a GPU's default), steps on MuJoCo:
    its Dataset records the engine asked for, the one that stepped it and why; its trajectory is the
    MuJoCo backend's, bitwise."""
    pytest.importorskip("mujoco_warp")
    import numpy as np

    from undulate.params import Scene, SimOptions
    from undulate.simulation import simulate

    scene, opts = Scene(phases_rad=(0.0,)), SimOptions(duration_s=0.2, sample_rate_hz=20.0)
    with using(Execution(backend="warp", device="cpu", lone_swimmers="mujoco")):
        moved = simulate(scene, opts)
    assert (moved.attrs["engine"], moved.attrs["engine_requested"]) == ("mujoco", "warp")
    assert "lone swimmer" in moved.attrs["engine_reason"]
    with using(Execution()):
        ref = simulate(scene, opts)
    np.testing.assert_array_equal(moved["x"].values, ref["x"].values)
    with using(Execution(backend="warp", device="cpu", lone_swimmers="warp")):
        kept = simulate(scene, SimOptions(duration_s=0.02, sample_rate_hz=50.0))
    assert (kept.attrs["engine"], kept.attrs["engine_requested"]) == ("warp", "warp")


def test_a_study_says_once_which_runs_step_on_another_engine(capsys):
    pytest.importorskip("mujoco_warp")
    from undulate.studies._staging import _engine_note

    note = _engine_note("toy", Execution(backend="warp", device="cpu", cores_up_to=4), progress=True)
    assert "batches of up to 4 scenes step on mujoco" in note
    assert capsys.readouterr().err.count("toy: ") == 1
    assert _engine_note("toy", Execution(), progress=True) is None


# ------------------------------------------------------------------ the docs' table
@pytest.mark.parametrize("page", ["README.md", "docs/guide/execution.md"])
def test_the_docs_table_names_every_setting(page):
    """The README and the guide explain the settings in one table: Python name, CLI option, environment
    variable, meaning, one row per setting, as :data:`undulate.execution.SETTINGS` has them."""
    text = (SRC.parents[1] / page).read_text()
    rows = [line for line in text.splitlines() if line.startswith("| `") and "`UNDULATE_" in line]
    want = [f"| `{s.name}` | " + (f"`{s.cli}`" if s.cli else "-") + f" | `{s.env}` | {s.meaning} |" for s in SETTINGS]
    assert rows == want
