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
