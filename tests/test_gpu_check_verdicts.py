"""The GPU check's verdict comparison (``benchmarks/bench_gpu_check.py``), which runs for the first time
on a device lease: a reproduction cut short by the check's budget still has its finished studies'
verdicts compared, and a claim it did not reach is not reported as a difference."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest

XI1, XI34, XI32 = (f"pairs:xi = {x}: contact drives pairs to a steady dx that follows the compatibility line"
                   for x in ("1", "3/4", "3/2"))
G3 = "groups:groups of 3 follow the compatibility line with more scatter than pairs"


@pytest.fixture(scope="module")
def check(benchmark_script):
    return benchmark_script("bench_gpu_check")


def _study_file(out: Path, study: str, verdicts: dict) -> None:
    """A study's NAME.json as a reproduction writes it (the fields the check reads)."""
    (out / f"{study}.json").write_text(json.dumps({"study": study, "claims": [
        {"study": study, "claim": k.split(":", 1)[1], "verdict": v} for k, v in verdicts.items()]}))


def test_a_cut_short_reproduction_compares_the_studies_it_finished(check, tmp_path):
    out = tmp_path / "repro-full-warp"
    out.mkdir()
    _study_file(out, "pairs", {XI1: "holds", XI34: "holds", XI32: "fails"})
    (out / "reproduce.json").write_text(json.dumps({"studies": {"pairs": {"ok": True}}}))
    (out / "groups.json").write_text('{"study": "gro')  # being written when the run was stopped
    got = check.study_verdicts(out)
    assert got == {XI1: "holds", XI34: "holds", XI32: "fails"}

    cpu = {"verdicts": {XI1: "holds", XI34: "undecided", XI32: "explained", G3: "holds"}}
    c = check.compare_verdicts(cpu, {"verdicts": got, "verdicts_from": check.STUDY_FILES})
    assert c["same"] == 1
    assert c["differ"] == {XI34: ["undecided", "holds"]}
    assert c["explanation_not_reached"] == [XI32]  # fails in its study; the sensitivity study not reached
    assert c["not_reached"] == [G3]


def test_a_finished_reproductions_claims_are_compared_whole(check):
    """From claims.json a fails where MuJoCo has explained is a real difference (the explanation ran)."""
    cpu = {"verdicts": {XI1: "holds", XI32: "explained"}}
    c = check.compare_verdicts(cpu, {"verdicts": {XI1: "holds", XI32: "fails"}})
    assert (c["same"], c["differ"], c["explanation_not_reached"], c["not_reached"]) == (
        1, {XI32: ["explained", "fails"]}, [], [])
    assert check.compare_verdicts(cpu, {})["not_reached"] == [XI1, XI32]


def _side_by_side(ms_per_step: dict) -> dict:
    """A side-by-side script's json (bench_warp_side_by_side.py): device ms a step per model count."""
    return {"rows": [{"models": k, "device_ms_per_step": v, "end_to_end_ms_per_step": v,
                      "merged_device_ms_per_step": v} for k, v in ms_per_step.items()]}


def test_more_hardware_queues_are_kept_only_where_they_cut_the_crowded_step(check):
    default = _side_by_side({1: 0.35, 16: 5.6})
    assert check.more_queues_help(default, _side_by_side({1: 0.35, 16: 0.9}))
    assert not check.more_queues_help(default, _side_by_side({1: 0.35, 16: 5.0}))  # within 20 %: not worth a change
    assert not check.more_queues_help(default, _side_by_side({1: 0.35}))  # not the same crowd measured
    assert not check.more_queues_help(default, "timeout")
    assert not check.more_queues_help(None, _side_by_side({1: 0.35, 16: 0.9}))
    assert not check.more_queues_help(_side_by_side({1: 0.4}), _side_by_side({1: 0.2}))  # one model: no crowd


@pytest.fixture(scope="module")
def src_copy(tmp_path_factory, benchmark_script):
    """A copy of the package's source tree and its reproduction digest, made once for the module (each
    test edits one file and puts it back)."""
    import shutil

    ref = benchmark_script("bench_gpu_check_reference")
    root = tmp_path_factory.mktemp("src") / "undulate"
    shutil.copytree(ref.SRC, root, ignore=shutil.ignore_patterns("__pycache__"))
    before = ref.src_digest(root)
    assert before == ref.src_digest(ref.SRC)
    return ref, root, before


@pytest.mark.parametrize("edited, moves", [
    ("studies/packing.py", True),          # a study
    ("simulation/_mujoco.py", True),       # the engine it reaches through imports
    ("cli.py", True),                      # the command's options and defaults
    ("robot/runner.py", False),            # the robot driver: not run by a reproduction
    ("track/tracker.py", False),
    ("simulation/_warp.py", False),        # the Warp backend: not MuJoCo's results
])
def test_the_cpu_references_digest_follows_the_code_a_reproduction_runs(src_copy, edited, moves):
    """The GPU check's CPU reference is valid while its digest matches: an edit a reproduction on the
    MuJoCo backend runs moves it, an edit elsewhere in the package does not."""
    ref, root, before = src_copy
    assert ref.src_digest(root) == before  # the copy as made (every earlier test put its file back)
    files = ref.reproduction_files(root)
    assert "reproduce.py" in files and "studies/packing.py" in files and (edited in files) is moves
    text = (root / edited).read_bytes()
    try:
        (root / edited).write_bytes(text + b"\n# an edit\n")
        assert (ref.src_digest(root) != before) is moves
    finally:
        (root / edited).write_bytes(text)


def test_the_lease_plan_names_a_cpu_reference_that_exists():
    """docs/gpu.md's lease command gives the check its MuJoCo verdicts (``--cpu-verdicts FILE``): the file
    it names is in the repository and holds a quick and a full reproduction's 17 paper verdicts each with
    the digest of the sources they came from (a remake's edit once left the command naming no file)."""
    import re

    root = Path(__file__).resolve().parents[1]
    plan = (root / "docs" / "gpu.md").read_text()
    named = re.findall(r"gpu_check_lease\.sh [^`]*--cpu-verdicts (\S+?)`", plan)
    assert named, "docs/gpu.md: no lease command with --cpu-verdicts FILE"
    for rel in set(named):
        ref = json.loads((root / rel).read_text())
        for mode in ("quick", "full"):
            assert len(ref[mode]["verdicts"]) == 17 and len(ref[mode]["src_sha256"]) == 64


def test_the_warp_timeline_summary_counts_models_at_once_and_steps_per_model(benchmark_script, tmp_path):
    """``benchmarks/bench_warp_timeline.py`` on a timeline worked out by hand: models A and B (one
    structure, 18 worlds) step [0, 1] s together, A again [1.5, 2.5], C (another structure, 1 world,
    its first chunk) [2, 3]; Unix times as the backend writes them, A's chunks on two lines."""
    tl = benchmark_script("bench_warp_timeline")
    t0 = 1.8e9
    s1, s2 = [10, 10, 4, 17, 14, 0.0006], [15, 15, 6, 25, 20, 0.0006]
    pa, pb, pk = "pairs/xi-1-quick-seed0", "pairs/xi-3-quick-seed0", "packing/brackets-1-quick-seed0"
    lines = [{"pid": 1, "group": 0, "structure": s1, "nworld": 18, "device": "cuda:0", "label": pa,
              "chunks": [[t0, 1.0, 100, 0]]},
             {"pid": 1, "group": 1, "structure": s1, "nworld": 18, "device": "cuda:0", "label": pb,
              "chunks": [[t0, 1.0, 100, 0]]},
             {"pid": 1, "group": 2, "structure": s2, "nworld": 1, "device": "cuda:0", "label": pk,
              "chunks": [[t0 + 2, 1.0, 10, 1]]},
             {"pid": 1, "group": 0, "structure": s1, "nworld": 18, "device": "cuda:0", "label": pa,
              "chunks": [[t0 + 1.5, 1.0, 50, 0]]}]
    path = tmp_path / "timeline.jsonl"
    path.write_text("".join(json.dumps(x) + "\n" for x in lines))
    s = tl.summarise(tl.load(path))
    gz = tmp_path / "timeline.jsonl.gz"
    gz.write_bytes(gzip.compress(path.read_bytes()))
    assert tl.summarise(tl.load(gz)) == s  # a timeline kept compressed (benchmarks/results) reads the same
    assert (s["models"], s["structures"], s["chunks"], s["world_steps"]) == (3, 2, 4, 150 * 18 + 100 * 18 + 10)
    assert s["span_s"] == pytest.approx(3.0, abs=1e-6) and s["no_model_s"] == pytest.approx(0.5, abs=1e-6)
    assert s["models_at_once"]["mean"] == pytest.approx(4 / 2.5, abs=1e-5) and s["models_at_once"]["max"] == 2
    assert s["structures_at_once"]["mean"] == pytest.approx(3 / 2.5, abs=1e-5) and s["structures_at_once"]["max"] == 2
    assert s["first_chunks_s"] == pytest.approx(1.0)
    # A and B's first chunks stepped two at once (10 ms a step); A's second, 1.5 on average (20 ms); C compiled
    assert set(s["ms_per_step"]) == {"1", "2-3"}
    assert s["ms_per_step"]["2-3"] == {"ms_per_step": pytest.approx(10.0, rel=1e-5), "chunks": 2, "steps": 200}
    assert s["ms_per_step"]["1"] == {"ms_per_step": pytest.approx(20.0, rel=1e-5), "chunks": 1, "steps": 50}
    assert s["host_share"] == pytest.approx(0.5 / 4.5, abs=1e-5)  # A's 0.5 s between its chunks
    # B began with A (one structure): a gatherer could have stepped B's worlds in A's model; C is alone
    for w in ("1s", "5s"):
        assert s["joinable"][w] == {"models": 1, "world_step_share": pytest.approx(1800 / 4510)}
    # per study, in order of ending: pairs (A and B, two sweeps) [0, 2.5] s, packing (C) [2, 3] s
    assert list(s["studies"]) == ["pairs", "packing"]
    # pairs' B began while A stepped: one wave, its chain A's 150 steps
    assert s["studies"]["pairs"] == {"models": 2, "sweeps": 2, "world_steps": 4500, "waves": 1, "chain_steps": 150,
                                     "first_s": pytest.approx(0.0), "last_s": pytest.approx(2.5, abs=1e-6)}
    assert s["studies"]["packing"] == {"models": 1, "sweeps": 1, "world_steps": 10, "waves": 1, "chain_steps": 10,
                                       "first_s": pytest.approx(2.0, abs=1e-6), "last_s": pytest.approx(3.0, abs=1e-6)}
    # a model D of C's structure beginning 3 s after C: joinable within 5 s, not within 1 s; without a
    # label (a timeline written before labels, or a call not gathered) its study is "-"
    d = {"model": (1, 3), "structure": tuple(s2), "nworld": 1, "device": "cuda:0",
         "chunks": np.array([[t0 + 5, 1.0, 30, 0]])}
    models = tl.load(path) + [d]
    assert tl.joinable(models, 1.0)["models"] == 1 and tl.joinable(models, 5.0) == {
        "models": 2, "world_step_share": pytest.approx((1800 + 30) / (4510 + 30))}
    assert tl.by_study(models)["-"] == {"models": 1, "sweeps": 1, "world_steps": 30, "waves": 1, "chain_steps": 30,
                                        "first_s": pytest.approx(5.0, abs=1e-6), "last_s": pytest.approx(6.0, abs=1e-6)}
    # a packing model E after C had ended: a second wave, the chain C's steps then E's
    e = {"model": (1, 4), "structure": tuple(s2), "nworld": 3, "device": "cuda:0", "label": pk,
         "chunks": np.array([[t0 + 3.5, 0.5, 20, 0], [t0 + 4.0, 0.5, 20, 0]])}
    assert tl.by_study(tl.load(path) + [e])["packing"]["waves"] == 2
    assert tl.by_study(tl.load(path) + [e])["packing"]["chain_steps"] == 10 + 40
