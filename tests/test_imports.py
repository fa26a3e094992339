"""The package's import graph has no cycle (every import counts, lazy ones too)."""

from __future__ import annotations

from undulate._source import closure, find_cycle, import_graph


def test_no_import_cycles_in_the_package():
    graph = import_graph()
    assert "undulate.studies.pairs" in graph and "undulate.cli" in graph
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def test_the_cycle_finder_finds_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_lazy_imports_are_edges():
    # simulate_point imports the simulator inside its body: the edge is there all the same
    graph = import_graph()
    assert "undulate.simulation" in closure(["undulate.studies.pairs"], graph)
    assert "undulate.plotting.pairs" in graph["undulate.studies.pairs"]



def test_no_study_imports_another_study():
    graph = import_graph()
    studies = {m for m in graph if m.startswith("undulate.studies.") and not m.split(".")[-1].startswith("_")}
    assert {"undulate.studies.pairs", "undulate.studies.packing"} <= studies
    for m in sorted(studies):
        assert not (graph[m] & studies), f"{m} imports {sorted(graph[m] & studies)}"


def test_every_public_name_is_what_the_api_lists_whichever_module_was_imported_first():
    """``undulate.<name>`` for each lazily loaded name is the object it stands for, in a fresh process that
    imported every submodule first: Python sets a package's attribute to a submodule of the same name on
    import, and ``undulate.animate`` (the function) once became the module ``undulate/animate.py``, not
    callable, after anything had imported that module."""
    import subprocess
    import sys

    code = ("import importlib, pkgutil, types, undulate\n"
            "for m in pkgutil.walk_packages(undulate.__path__, 'undulate.'):\n"
            "    if not m.name.startswith(('undulate.robot', 'undulate.track')) and m.name != 'undulate.__main__':\n"
            "        importlib.import_module(m.name)\n"
            "for name, (mod, attr) in undulate._LAZY.items():\n"
            "    want = importlib.import_module('undulate.' + mod)\n"
            "    want = want if attr is None else getattr(want, attr)\n"
            "    assert getattr(undulate, name) is want, (name, getattr(undulate, name))\n"
            "assert not isinstance(undulate.animate, types.ModuleType)\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
