"""``examples/drag_study.py``, the study a newcomer wrote by following docs/guide/studies.md, keeps
working: it registers on import, its looks nest, and it runs through the registry in quick mode to
judged claims, reusing every run on a second call."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "drag_study.py"


@pytest.fixture
def drag_study():
    from undulate.studies import _registry

    _registry._load()
    spec = importlib.util.spec_from_file_location("drag_study", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    sys.modules["drag_study"] = module  # as an import would (its dataclass needs it)
    spec.loader.exec_module(module)
    yield module
    _registry._REGISTRY.pop("drag", None)
    sys.modules.pop("drag_study", None)


def test_the_example_study_registers_nests_and_runs_to_judged_claims(tmp_path, drag_study):
    from undulate import studies
    from undulate.studies._staging import stage_plans

    info = studies.describe("drag")
    assert "drag" in studies.names() and info.reference == "paper" and len(info.claims) == 2
    for quick in (True, False):
        looks = stage_plans(info, quick)
        assert looks[-1] == info.plan(quick)
        for a, b in zip(looks, looks[1:]):
            assert set(a.dphi_rad) <= set(b.dphi_rad) and a.drag_N_s_per_m == b.drag_N_s_per_m
    studies.run_study("drag", tmp_path, quick=True, workers=1, progress=False)
    doc = json.loads((tmp_path / "drag.json").read_text())
    assert doc["n_failed"] == 0 and doc["n_computed"] > 0
    assert [c["verdict"] in ("holds", "fails", "undecided") for c in doc["claims"]] == [True, True], doc["claims"]
    rms = doc["summary"]["rms_shift_over_lambda"]
    assert rms["method"] == "bootstrap BCa over clusters" and rms["ci95"][0] <= rms["value"] <= rms["ci95"][1]
    assert {p.suffix for p in tmp_path.glob("drag.*")} == {".nc", ".png", ".pdf", ".json"}
    studies.run_study("drag", tmp_path, quick=True, workers=1, progress=False)
    again = json.loads((tmp_path / "drag.json").read_text())
    assert again["n_computed"] == 0 and again["claims"] == doc["claims"]
