"""Three-valued verdicts, look-corrected intervals and staged plans (issue 36).

* the verdict logic on constructed intervals: inside, outside, straddling, several criteria;
* the look-corrected interval's error rate, by simulation: with the true value on the boundary,
  ``holds`` in at most 5 % of repetitions;
* a staged study stops adding runs once decided, reuses every earlier run, reaches the whole
  plan's verdict where the whole plan decides, and resumes after a kill mid-stage to the same
  result (real sweeps of a real MuJoCo pendulum; ``staged_study.py``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from undulate import stats
from undulate.stats import Check, Estimate, decide
from undulate.errors import UndulateError
from undulate.studies._protocol import FAILS, HOLDS, NO_RESULT, UNDECIDED, Verdict

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))


# ---- the verdict logic on constructed intervals -----------------------------------------------
def E(lo, hi, n=10):
    return Estimate((lo + hi) / 2, (hi - lo) / 4, lo, hi, n, "t")


@pytest.mark.parametrize("lo, hi, state", [
    (0.9, 1.1, True),      # inside [0.8, 1.2]
    (0.8, 1.2, True),      # the boundary itself is inside
    (0.3, 0.7, False),     # wholly below
    (1.3, 1.7, False),     # wholly above
    (0.7, 1.0, None),      # straddles 0.8
    (1.0, 1.3, None),      # straddles 1.2
    (0.5, 1.5, None),      # straddles both
])
def test_within_has_three_outcomes(lo, hi, state):
    c = E(lo, hi).within(0.8, 1.2, "slope")
    assert c.state is state
    if state is None:
        assert "straddles" in c.text and ("0.8" in c.text or "1.2" in c.text)


def test_one_sided_checks_and_no_interval():
    assert E(0.1, 0.4).below(0.5).state is True
    assert E(0.6, 0.9).below(0.5).state is False
    assert E(0.35, 0.99).below(0.5).state is None  # the contact-force ratio: not "fails"
    assert E(0.6, 0.9).above(0.5).state is True
    assert Estimate(0.7).within(0, 1).state is None  # no interval: undecided, never holds
    assert Check.apart(E(2, 3), E(0, 1), "a > b").state is True
    assert Check.apart(E(0, 1), E(2, 3), "a > b").state is False
    assert Check.apart(E(0, 2), E(1, 3), "a > b").state is None


def test_runs_needed_scales_as_one_over_root_n_without_a_t_quantile():
    # value 0.955, half-width below 0.173, boundary 0.8 at distance 0.155: (0.173/0.155)^2 * 9 runs (an
    # estimate that records no dof; the t quantile's fall with the runs: tests/test_runs_needed.py)
    c = Estimate(0.955, 0.08, 0.782, 1.129, 9).within(0.8, 1.2)
    assert c.runs_needed == math.ceil(9 * (0.173 / 0.155) ** 2)
    assert Estimate(0.8, 0.1, 0.6, 1.0, 9).within(0.8, 1.2).runs_needed is None  # on the boundary


@pytest.mark.parametrize("states, verdict", [
    ((True, True), HOLDS),
    ((True, False), FAILS),
    ((None, False), FAILS),      # one criterion fails: the claim fails
    ((True, None), UNDECIDED),   # none fails, one straddles
    ((None, None), UNDECIDED),
])
def test_several_criteria(states, verdict):
    checks = [Check(s, f"c{i}", 5 + i if s is None else None) for i, s in enumerate(states)]
    v = Verdict.of(checks, "m")
    assert v.verdict == verdict
    assert decide(checks) is {HOLDS: True, FAILS: False, UNDECIDED: None}[verdict]
    if verdict == UNDECIDED:
        assert v.runs_needed == max(c.runs_needed for c in checks if c.state is None)
        assert all(c.text in v.reason for c in checks if c.state is None)


def test_look_levels_spend_alpha_once():
    for k in range(1, 7):
        levels = stats.look_levels(k)
        assert len(levels) == k and sum(1 - lv for lv in levels) == pytest.approx(1 - stats.CONFIDENCE)
    assert stats.look_levels(1) == (stats.CONFIDENCE,)
    with stats.at_level(0.99):
        e = stats.mean(np.arange(10.0))
    assert e.level == 0.99 and stats.level() == stats.CONFIDENCE
    wide = e.high - e.low
    narrow = stats.mean(np.arange(10.0))
    assert wide > narrow.high - narrow.low


# ---- the error rate of a staged decision, by simulation ---------------------------------------
def _staged_holds(rng, stages, levels, truth, boundary, corrected):
    """One staged trial: draw normal samples, look after each stage, stop once decided; True if
    the trial ended with ``holds`` (interval wholly above ``boundary``; the truth is on it)."""
    x = rng.normal(truth, 1.0, stages[-1])
    for n, lv in zip(stages, levels):
        with stats.at_level(lv if corrected else stats.CONFIDENCE):
            c = stats.mean(x[:n]).above(boundary)
        if c.state is not None:
            return c.state is True
    return False


def test_look_corrected_holds_at_most_five_percent_on_the_boundary():
    """The true mean sits on the region's boundary, so ``holds`` is wrong every time it is said:
    over 4000 staged trials (looks after 10, 20, 40 samples) it is said in at most 5 % of them."""
    rng = np.random.default_rng(36)
    stages = (10, 20, 40)
    levels = stats.look_levels(len(stages))
    reps = 4000
    corrected = sum(_staged_holds(rng, stages, levels, 0.0, 0.0, True) for _ in range(reps)) / reps
    assert corrected <= 0.05
    # the uncorrected looks wrong more often than the corrected ones (same seeds)
    rng = np.random.default_rng(36)
    naive = sum(_staged_holds(rng, stages, levels, 0.0, 0.0, False) for _ in range(reps)) / reps
    assert corrected < naive


# ---- the staged registry: real sweeps ----------------------------------------------------------
@pytest.fixture
def staged(monkeypatch):
    import staged_study

    from undulate.studies import _registry

    yield staged_study
    for name in ("_staged", "_whole"):
        _registry._REGISTRY.pop(name, None)
    sys.modules.pop("staged_study", None)


def _doc(out, name):
    return json.loads((Path(out) / f"{name}.json").read_text())


def test_a_decided_claim_stops_the_stages(tmp_path, staged, monkeypatch):
    from undulate.studies import run_study

    monkeypatch.setattr(staged, "REGION", (-5.0, 5.0))  # decided at the first look
    run_study("_staged", tmp_path, workers=1, progress=False)
    doc = _doc(tmp_path, "_staged")
    assert [s["stage"] for s in doc["stages"]] == [1]
    assert doc["claims"][0]["verdict"] == HOLDS
    assert doc["n_computed"] == staged.STAGE_POINTS[0]
    assert doc["claims"][0]["value"]["mean_start_angle"]["level"] == stats.look_levels(3)[0]


def test_an_undecided_claim_adds_stages_and_reuses_runs(tmp_path, staged, monkeypatch):
    from undulate.studies import run_study

    # first look: the interval of the mean straddles -1 with the estimate far enough from it that
    # the cap's runs should decide it (not futile): stages are added, each computing only its new runs
    monkeypatch.setattr(staged, "REGION", (-1.0, 5.0))
    run_study("_staged", tmp_path, workers=1, progress=False)
    doc = _doc(tmp_path, "_staged")
    looks = doc["stages"]
    assert len(looks) >= 2
    assert [s["n_computed"] for s in looks] == [6, 6, 12][:len(looks)]  # each stage computes only its new points
    for s in looks[:-1]:
        assert s["undecided"]  # a stage is added only while the claim is undecided (and decidable)
    assert [s["confidence_level"] for s in looks] == list(stats.look_levels(3)[:len(looks)])


def test_no_result_at_a_look_adds_a_stage(tmp_path, staged, monkeypatch):
    """A claim with ``no result`` at a look (too few runs for its number) is open, not decided: the next
    stage is run, and its runs decide it (quick mode too: no futility estimate without an interval)."""
    from undulate.studies import run_study

    monkeypatch.setattr(staged, "REGION", (-5.0, 5.0))
    monkeypatch.setattr(staged, "MIN_POINTS", 7)  # the first look's 6 runs give no result
    monkeypatch.setattr(staged, "STAGE_POINTS", (6, 12))
    run_study("_staged", tmp_path, quick=True, workers=1, progress=False)
    doc = _doc(tmp_path, "_staged")
    claim = doc["claims"][0]
    assert [s["verdicts"][claim["claim"]] for s in doc["stages"]] == [NO_RESULT, HOLDS]
    assert doc["stages"][0]["undecided"] == [claim["claim"]] and not doc["stages"][0]["futile"]
    assert claim["verdict"] == HOLDS and claim["decided_at"]["stage"] == 2


def test_a_claim_the_cap_cannot_decide_stops_for_futility(tmp_path, staged, monkeypatch):
    """Quick mode: the true mean 0 sits on the boundary, so the first look's interval straddles it with
    the estimate so near that even the cap's 2x runs would not decide it.  No stage is added; the claim
    stays undecided, with the runs it would need (a futility stop never says holds or fails)."""
    from undulate.studies import run_study

    monkeypatch.setattr(staged, "REGION", (0.0, 5.0))
    monkeypatch.setattr(staged, "STAGE_POINTS", (6, 12))  # quick mode's two looks (strides 2, 1)
    run_study("_staged", tmp_path, quick=True, workers=1, progress=False)
    doc = _doc(tmp_path, "_staged")
    claim = doc["claims"][0]
    assert claim["verdict"] == UNDECIDED and claim["runs_needed"] > 0
    assert claim["growth_needed"] > 2
    assert [s["stage"] for s in doc["stages"]] == [1] and doc["stages"][0]["futile"] == [claim["claim"]]
    # full mode decides: it runs to its cap while the claim is undecided, futile or not
    monkeypatch.setattr(staged, "STAGE_POINTS", (6, 12, 24))
    run_study("_staged", tmp_path / "full", workers=1, progress=False)
    looks = _doc(tmp_path / "full", "_staged")["stages"]
    assert looks[-1]["verdicts"] != {claim["claim"]: UNDECIDED} or len(looks) == 3


@pytest.mark.parametrize("region", [(-2.0, 2.0), (1.5, 3.0), (-3.0, -1.2)])
def test_staged_verdict_equals_the_whole_plans_where_it_decides(tmp_path, staged, monkeypatch, region):
    from undulate.studies import run_study

    monkeypatch.setattr(staged, "REGION", region)
    run_study("_whole", tmp_path / "whole", workers=1, progress=False)
    run_study("_staged", tmp_path / "staged", workers=1, progress=False)
    whole = _doc(tmp_path / "whole", "_whole")["claims"][0]["verdict"]
    assert whole in (HOLDS, FAILS)
    assert _doc(tmp_path / "staged", "_staged")["claims"][0]["verdict"] == whole


_RUN = textwrap.dedent("""
    import sys
    sys.path.insert(0, {here!r})
    import staged_study
    staged_study.REGION = (-1.0, 5.0)
    from undulate.studies import run_study
    run_study("_staged", {out!r}, workers=1, progress=False)
""")


def _run_in_subprocess(out, env):
    return subprocess.run([sys.executable, "-c", _RUN.format(here=str(HERE), out=str(out))], env=env,
                          capture_output=True, text=True, timeout=300)


def test_killed_mid_stage_resumes_to_the_same_result(tmp_path):
    """SIGKILL during stage 2 (one run of it already stored), then run again: the same claims,
    summary and stages as a run never interrupted, and the stored runs are reused."""
    env = {**os.environ, "STAGED_KILL_MARKER": str(tmp_path / "killed")}
    first = _run_in_subprocess(tmp_path / "a", env)
    assert first.returncode == -9 and (tmp_path / "killed").exists()
    assert not (tmp_path / "a" / "_staged.json").exists()  # nothing written half-way
    again = _run_in_subprocess(tmp_path / "a", env)
    assert again.returncode == 0, again.stderr
    clean = _run_in_subprocess(tmp_path / "b", {k: v for k, v in os.environ.items() if k != "STAGED_KILL_MARKER"})
    assert clean.returncode == 0, clean.stderr
    a, b = _doc(tmp_path / "a", "_staged"), _doc(tmp_path / "b", "_staged")
    for key in ("claims", "summary"):
        assert a[key] == b[key]
    assert [(s["stage"], s["n_runs"], s["verdicts"]) for s in a["stages"]] == \
        [(s["stage"], s["n_runs"], s["verdicts"]) for s in b["stages"]]
    assert sum(s["n_computed"] for s in a["stages"]) < sum(s["n_runs"] for s in a["stages"])  # reused


# ---- every study's stages nest and end at its whole plan ---------------------------------------
def _fields(p):
    import dataclasses

    if isinstance(p, dict):
        d = p
    elif dataclasses.is_dataclass(p):
        d = {f.name: getattr(p, f.name) for f in dataclasses.fields(p)}
    elif p is None:
        return {}
    elif isinstance(p, (list, tuple, np.ndarray)):
        d = {"values": p}
    elif hasattr(p, "__dict__"):
        d = vars(p)
    else:
        d = {k: getattr(p, k) for k in p.__slots__}
    def flat(v):
        if isinstance(v, np.ndarray):
            return v.ravel().tolist()
        return [repr(np.asarray(x).tolist()) if isinstance(x, (list, tuple, dict, np.ndarray)) else x for x in v]

    return {k: (flat(v) if isinstance(v, (list, tuple, np.ndarray)) else v) for k, v in d.items()}


@pytest.mark.parametrize("quick", [True, False])
def test_every_studys_stages_nest_and_end_at_its_plan(quick):
    from undulate import studies
    from undulate.studies._registry import describe
    from undulate.studies._staging import stage_plans

    for name in studies.names():
        info = describe(name)
        plans = [_fields(p) for p in stage_plans(info, quick)]
        assert plans[-1] == _fields(info.plan(quick)), name
        for a, b in zip(plans, plans[1:]):
            for key, va in a.items():
                vb = b[key]
                if isinstance(va, list):  # a grid: every value of a look is in the next look
                    assert set(va) <= set(vb), (name, key)
                elif isinstance(va, (int, float)) and key in ("draws", "replicates", "group_draws",
                                                               "heatmap_draws", "refine"):
                    assert va <= vb, (name, key)
                else:
                    assert va == vb, (name, key)


def test_refined_grids_keep_the_coarse_values_bitwise():
    """A cap refined from a coarser grid holds that grid's values bitwise (a finer linspace does not:
    385 over [-pi, pi] differs from 33 in the last bit), so its runs are found again in the stores."""
    from undulate.studies import _analysis as C

    g = C.phase_grid(33)
    assert not np.array_equal(C.phase_grid(385)[::12], g)  # why refined exists
    for k in (1, 2, 3, 12):
        r = C.refined(g, k)
        assert r.size == 32 * k + 1 and np.array_equal(r[::k], g)
        assert np.allclose(np.diff(r), 2 * np.pi / (32 * k), rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="refined"):
        C.refined(g, 0)


def test_bootstrap_estimates_carry_the_level_they_were_formed_at():
    """Inside a look every interval is formed at the look's level, and the estimate must say so (its
    measured text names the level): the potential study's collapse scatter and stiffness offset."""
    from undulate.studies import potential

    rng = np.random.default_rng(1)
    x = np.repeat([0.6, 0.8, 1.0, 1.2, 1.4], 3)
    logk = -x + 0.05 * rng.standard_normal(x.size)
    forces = np.array([0.01, 0.02, 0.05, 0.1, 0.2])
    with stats.at_level(0.975):
        e = potential._collapse_rms(x, logk)
        fit = potential.stiffness_fit(forces, 0.01 + forces / 5.0 + 1e-4 * rng.standard_normal(forces.size))
    assert e.level == 0.975 and fit["dx0"].level == 0.975
    assert "97.5 % intervals" in stats.interval_note(e.level)


def test_prefetching_the_last_stage_keeps_the_staged_looks(tmp_path, staged, monkeypatch):
    """The Warp backend on a GPU steps the last stage's runs first (a stage costs a GPU about the same
    at any number of worlds); the looks then read them from the stores and must be the staged plan's own:
    the same stages, levels, runs and verdicts, with nothing computed at the looks."""
    from undulate.studies import _staging, run_study

    monkeypatch.setattr(staged, "REGION", (-1.0, 5.0))  # undecided at the first look: stages are added
    run_study("_staged", tmp_path / "staged", workers=1, progress=False)
    monkeypatch.setattr(_staging, "_prefetching", lambda execution: True)
    run_study("_staged", tmp_path / "prefetched", workers=1, progress=False)
    plain, pre = _doc(tmp_path / "staged", "_staged"), _doc(tmp_path / "prefetched", "_staged")
    assert plain["prefetched"] is None
    assert pre["prefetched"]["n_computed"] == pre["prefetched"]["n_runs"] == staged.STAGE_POINTS[-1]
    keys = ("stage", "of", "confidence_level", "n_runs", "verdicts", "undecided", "futile")
    assert [{k: s[k] for k in keys} for s in pre["stages"]] == [{k: s[k] for k in keys} for s in plain["stages"]]
    assert len(plain["stages"]) >= 2 and all(s["n_computed"] == 0 for s in pre["stages"])
    assert pre["claims"][0]["verdict"] == plain["claims"][0]["verdict"]
    assert pre["summary"] == plain["summary"]
    assert sum(1 for s in pre["sweeps"] if s.get("prefetch")) == 1


@pytest.mark.parametrize("backend, device, env, expected", [
    ("mujoco", None, None, False),
    ("warp", "cuda", None, True),
    ("warp", "cpu", "0", False),
    ("warp", "cpu", None, False),  # each world costs its own steps there: only the looks' runs
    ("warp", "cpu", "1", True),
    ("warp", "cuda", "0", False),
    ("mujoco", None, "1", False),  # the setting is the Warp backend's
])
def test_studies_step_their_last_stage_first_on_a_gpu_only(monkeypatch, backend, device, env, expected):
    """The prefetch rule (:func:`undulate.execution.prefetch`): by device, unless
    ``UNDULATE_WARP_PREFETCH`` says; a study on the Warp backend still runs wide on either device."""
    from undulate.execution import current, runs_wide
    from undulate.studies import _staging

    monkeypatch.setenv("UNDULATE_BACKEND", backend)
    for var, value in (("UNDULATE_DEVICE", device), ("UNDULATE_WARP_PREFETCH", env)):
        if value is None:
            monkeypatch.delenv(var, raising=False)
        else:
            monkeypatch.setenv(var, value)
    assert _staging._prefetching(current()) is expected
    assert runs_wide(current().replace(workers=1)) is (backend == "warp")


def test_a_prefetch_setting_other_than_1_or_0_is_refused(monkeypatch):
    from undulate.errors import ParameterError
    from undulate.execution import prefetch

    monkeypatch.setenv("UNDULATE_WARP_PREFETCH", "yes")
    with pytest.raises(ParameterError, match="UNDULATE_WARP_PREFETCH"):
        prefetch("cuda")  # the settings are read first: the variable is named


def test_a_decided_claim_stays_decided_while_the_study_runs_on(tmp_path, staged, monkeypatch):
    """Three claims in one staged study, the last undecided to the cap (its true mean sits on its
    boundary), so every look runs.  One is decided at the first look (holds: fewer than 10 runs) and
    would fail at the later ones: it keeps its first look's row, level and value.  One holds at every
    look: decided at the first, its row is the last look's (the most runs).  Each is marked
    ``decided_at`` with what the later looks said on their own; the undecided one is the last look's."""
    from undulate.studies import Claim, Study, Verdict, register, run_study
    from undulate.studies._registry import _REGISTRY

    def count(s, below):
        n = len(s["angles"])
        return Verdict.judged(n < below, f"{n} runs", {"n": n})

    def summary(ds):
        return {**staged.summary(ds), "angles": [float(v) for v in ds["start_angle"].values]}

    monkeypatch.setattr(staged, "REGION", (0.0, 5.0))
    register(Study(name="_two", description="three claims", plan=lambda quick: staged.damping(24),
                   stages=lambda quick: tuple(staged.damping(n) for n in staged.STAGE_POINTS),
                   dataset=staged.dataset, summary=summary, figure=staged._figure,
                   claims=(Claim("fewer than 10 runs", "toy", "count < 10", lambda s: count(s, 10)),
                           Claim("fewer than 100 runs", "toy", "count < 100", lambda s: count(s, 100)),
                           staged.CLAIM)))
    try:
        run_study("_two", tmp_path, workers=1, progress=False)
    finally:
        _REGISTRY.pop("_two", None)
    doc = _doc(tmp_path, "_two")
    looks = doc["stages"]
    assert len(looks) == 3  # the mean on its boundary stays undecided to the cap
    assert [s["verdicts"]["fewer than 10 runs"] for s in looks] == [HOLDS, FAILS, FAILS]
    first, always, mean = doc["claims"]
    levels = stats.look_levels(3)
    assert first["verdict"] == HOLDS and first["value"] == {"n": 6} and first["measured"] == "6 runs"
    assert first["decided_at"] == {"stage": 1, "of": 3, "confidence_level": levels[0], "measured_at_stage": 1,
                                   "later_verdicts": [FAILS, FAILS]}
    assert always["verdict"] == HOLDS and always["value"] == {"n": 24}
    assert always["decided_at"] == {"stage": 1, "of": 3, "confidence_level": levels[0], "measured_at_stage": 3,
                                    "later_verdicts": [HOLDS, HOLDS]}
    assert mean["verdict"] == UNDECIDED and mean["decided_at"] is None
    assert mean["value"]["mean_start_angle"]["n"] == 24  # the last look's
    assert all(s["undecided"] == [staged.CLAIM.claim] for s in looks)


def test_later_looks_hand_a_decided_part_the_plan_that_decided_it(tmp_path, staged, monkeypatch):
    """The staging engine hands each look's dataset, for each part of the plan, the plan it follows: a
    part whose readers earlier looks decided (an explanation, a claim) keeps the deciding look's plan (the
    sensitivity study's frozen groups, the pairs study's frozen xi), and the study never sees the looks.
    A toy study whose own claim stays undecided to the cap (every look runs), whose count claim holds at
    the first look and whose explanation of another study's claim (verdict unknown here: needed) is shown
    at the first."""
    from undulate.studies import Claim, Explanation, Study, Verdict, register, run_study
    from undulate.studies._registry import _REGISTRY

    told, told_claims = [], []

    def dataset(ctx, plan):
        told.append(len(ctx.plan_for("explained", plan)))
        told_claims.append(len(ctx.plan_for("counted", plan)))
        with pytest.raises(UndulateError, match="no claim or explanation reads plan part 'nobody'"):
            ctx.plan_for("nobody", plan)
        return staged.dataset(ctx, plan)

    def summary(ds):
        return {**staged.summary(ds), "n": int(ds.sizes["run"])}

    few = Claim("fewer than 10 runs", "toy", "count < 10",
                lambda s: Verdict.judged(s["n"] < 10, f"{s['n']} runs", {"n": s["n"]}), reads=("counted",))

    monkeypatch.setattr(staged, "REGION", (0.0, 5.0))  # the mean sits on its boundary: undecided to the cap
    shown_once = Explanation("elsewhere", "a claim of another study", "toy cause",
                             lambda s: (True, "shown", None), reads=("explained",))
    register(Study(name="_explains", description="staged, with an explanation",
                   plan=lambda quick: staged.damping(24),
                   stages=lambda quick: tuple(staged.damping(n) for n in staged.STAGE_POINTS),
                   dataset=dataset, summary=summary, figure=staged._figure, claims=(staged.CLAIM, few),
                   explanations=(shown_once,)))
    try:
        run_study("_explains", tmp_path, workers=1, progress=False)
    finally:
        _REGISTRY.pop("_explains", None)
    first = staged.STAGE_POINTS[0]
    assert told == [first, first, first]  # shown at the first look: its runs stay the first look's
    assert told_claims == [first, first, first]  # held at the first look
    doc = _doc(tmp_path, "_explains")
    (row,) = doc["explanations"]
    assert row["shown"] is True and row["decided_at"]["stage"] == 1
    assert [s["frozen_parts"] for s in doc["stages"]] == [{}, {"counted": 1, "explained": 1},
                                                          {"counted": 1, "explained": 1}]


def _context_at(name, quick, final_claims):
    """A context of study ``name`` as the staging engine makes it for a look after earlier looks made
    ``final_claims`` (claim -> look) final (every explanation needed, none decided)."""
    from undulate.studies._context import StudyConfig, StudyContext
    from undulate.studies._registry import describe
    from undulate.studies._staging import part_plans, stage_plans

    info = describe(name)
    ctx = StudyContext(StudyConfig(out_dir="unused", quick=quick, workers=1), name, progress=False)
    ctx.parts = part_plans(info, stage_plans(info, quick), final_claims, {}, lambda study, claim: True)
    return ctx


@pytest.mark.parametrize("decided", [{}, {"4": 3}, {"3": 4, "4": 3}])
def test_a_group_size_whose_claim_is_decided_keeps_its_looks_runs(decided):
    """The groups study's fourth full look: a size whose claim an earlier look decided asks for that
    look's runs (fewer draws of four, fewer dphi of three); the reference pairs, which feed both claims,
    stay as they are until both are decided."""
    from undulate.studies import groups

    looks = groups.stages(False)
    claims = {c.claim.split()[2]: c.claim for c in groups.CLAIMS[:2]}
    spacing = {c.claim: 1 for c in groups.CLAIMS[2:]}  # read every size: decided at the first look here
    ctx = _context_at("groups", False, {**spacing, **{claims[n]: k for n, k in decided.items()}})
    got = {n: ctx.plan_for(groups.part(n), looks[3]) for n in (2, 3, 4)}
    assert got[3] == (looks[decided["3"] - 1] if "3" in decided else looks[3])
    assert got[4] == (looks[decided["4"] - 1] if "4" in decided else looks[3])
    assert got[2] == (looks[max(decided.values()) - 1] if len(decided) == 2 else looks[3])
    want = {int(n): k for n, k in decided.items()} | ({2: max(decided.values())} if len(decided) == 2 else {})
    assert ctx.parts.frozen_at == {groups.part(n): k for n, k in want.items()}
    if "4" in decided:
        assert got[4].draws < looks[3].draws


@pytest.mark.parametrize("decided, frozen", [
    ({}, {}),
    ({"0.75": 3}, {"0.75": 3}),
    ({"1": 2}, {}),  # xi = 1 also feeds the standing-wave claim, still open
    ({"1": 2, "standing": 3}, {"0": 3, "1": 3}),
])
def test_a_pairs_xi_whose_claims_are_decided_keeps_its_looks_runs(decided, frozen):
    """The pairs study's fourth full look (193 dphi): an xi every claim reading which an earlier look
    decided asks for that look's dphi only (made already); the dataset marks the rest not made (NaN, not
    failed) and the summary counts only the runs made."""
    import xarray as xr
    from types import SimpleNamespace

    from undulate.studies import pairs

    from undulate.studies._registry import describe
    from undulate.studies._staging import stage_plans

    looks = stage_plans(describe("pairs"), False)
    names = {"1": pairs.CLAIMS[0].claim, "0.75": pairs.CLAIMS[1].claim, "standing": pairs.CLAIMS[3].claim}
    asked = []

    staged_ctx = _context_at("pairs", False, {**{c.claim: 1 for c in pairs.CLAIMS[4:]},  # decided at the first
                                              **{names[k]: v for k, v in decided.items()}})

    class Ctx:
        seed = 0
        plan_for = staged_ctx.plan_for  # the staging engine's answer

        def sweep(self, part, fn, grid):  # every run failed: no simulation
            asked.extend(grid.points())
            n = len(asked)
            return xr.Dataset({"run_failed": (("point", "replicate"), np.ones((n, 1), bool))},
                              coords={"time": np.arange(3.0)})

        def together(self, *calls):
            return [call() for call in calls]

        def lone_swimmer(self, **kw):
            return {"amplitude_m": 0.05}

    ds = pairs.dataset(Ctx(), looks[3])
    assert staged_ctx.parts.frozen_at == {pairs.part(float(x)): k for x, k in frozen.items()}
    made = ds["run_made"].values
    for i, x in enumerate(ds["xi"].values):
        want = looks[frozen[f"{x:g}"] - 1].dphi_rad if f"{x:g}" in frozen else looks[3].dphi_rad
        got = [p["dphi_rad"] for p in asked if p["waves_per_body"] == x]
        assert got == list(want)
        assert (made[i] == np.isin(ds["dphi"].values, want)).all()
    assert len(asked) == made.sum() == ds["run_failed"].values.sum()
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = pairs.summary(ds)
    assert s["n_runs"] == len(asked) == s["n_failed"]


def test_a_futile_claims_runs_stay_where_it_was_found_futile(tmp_path, staged, monkeypatch):
    """Quick mode, two claims: the mean on its boundary is futile at the first look (the cap's runs
    would not decide it), while a claim with no result there (fewer than 7 runs) keeps the study going.
    The second look is told the futile claim is frozen at the first (its runs need not grow), and it
    stays futile there, whatever its growth estimate at the second look."""
    from undulate.studies import Claim, Study, Verdict, register, run_study
    from undulate.studies._registry import _REGISTRY

    told = []

    def dataset(ctx, plan):
        told.append(len(ctx.plan_for("mean", plan)))
        return staged.dataset(ctx, plan)

    def summary(ds):
        return {**staged.summary(ds), "n": int(ds.sizes["run"])}

    def seven(s):
        if s["n"] < 7:
            return Verdict.none(f"{s['n']} runs, fewer than 7", value={"n": s["n"]})
        return Verdict.judged(True, f"{s['n']} runs", {"n": s["n"]})

    monkeypatch.setattr(staged, "REGION", (0.0, 5.0))
    monkeypatch.setattr(staged, "STAGE_POINTS", (6, 12))  # quick mode's two looks (strides 2, 1)
    register(Study(name="_futile", description="a futile claim beside an open one",
                   plan=lambda quick: staged.damping(12),
                   stages=lambda quick: tuple(staged.damping(n) for n in staged.STAGE_POINTS),
                   dataset=dataset, summary=summary, figure=staged._figure,
                   claims=(dataclasses.replace(staged.CLAIM, reads=("mean",)),
                           Claim("at least 7 runs", "toy", "count >= 7", seven))))
    try:
        run_study("_futile", tmp_path, quick=True, workers=1, progress=False)
    finally:
        _REGISTRY.pop("_futile", None)
    doc = _doc(tmp_path, "_futile")
    first, second = doc["stages"]
    assert first["futile"] == [staged.CLAIM.claim] and first["undecided"] == ["at least 7 runs"]
    assert told == [6, 6]  # frozen at the first look: the second hands its part the first look's plan
    assert [s["frozen_parts"] for s in doc["stages"]] == [{}, {"mean": 1}]
    assert second["futile"] == [staged.CLAIM.claim] and second["undecided"] == []
    mean, seven_runs = doc["claims"]
    assert mean["verdict"] == UNDECIDED and seven_runs["verdict"] == HOLDS


def test_a_potential_sweep_whose_claims_are_final_keeps_its_looks_runs():
    """The potential study's impulse sweep feeds the impulse claim and the impulse-by-amplitude claim (its
    runs at the default beta; the runs at the other betas are that claim's own part), its force sweep the
    harmonic, k, collapse, amplitude and dx0 claims (each part frozen once all its readers are, at the latest
    such look); the release claim's runs are the same at every look and hold no sweep back.  Quick mode's
    impulse claims found futile or final at the first look leave the second look nothing to run: its force
    grid is the first look's already."""
    from undulate.studies import potential

    looks = potential.stages(False)
    impulse, harmonic, falls, collapse, amp, dx0, release, amp_impulse = (c.claim for c in potential.CLAIMS)
    both = {impulse: 2, amp_impulse: 2}

    def grids(p):
        return ((p.impulse_dphi, p.impulse_phi0), (p.betas_deg, p.d_over_2A, p.forces_N),
                (p.amplitude_betas_deg, p.amplitude_dphi, p.amplitude_phi0))

    for frozen, want_imp, want_force, want_amp in [
            ({}, 3, 3, 3), ({impulse: 1}, 3, 3, 3),  # the amplitude claim still open: the 45 deg runs go on
            ({impulse: 1, amp_impulse: 1}, 0, 3, 0), ({impulse: 1, amp_impulse: 2}, 1, 3, 1),
            ({amp_impulse: 1}, 3, 3, 0),  # its own runs stop; the impulse claim keeps the shared ones going
            ({harmonic: 1, falls: 2}, 3, 3, 3), ({harmonic: 1, falls: 3, collapse: 2}, 3, 3, 3),
            ({harmonic: 1, falls: 3, collapse: 2, dx0: 1}, 3, 3, 3),  # amp not final
            ({harmonic: 1, falls: 3, collapse: 2, amp: 1, dx0: 1}, 3, 2, 3),
            ({**both, harmonic: 2, falls: 2, collapse: 2, amp: 2, dx0: 2}, 1, 1, 1),
            ({**both, harmonic: 2, falls: 2, collapse: 2, amp: 2, dx0: 2, release: 3}, 1, 1, 1)]:
        ctx = _context_at("potential", False, frozen)
        got = potential.sweep_plan(looks[3], ctx.plan_for("impulse", looks[3]), ctx.plan_for("force", looks[3]),
                                   ctx.plan_for(potential.AMPLITUDE_PART, looks[3]))
        assert grids(got) == (grids(looks[want_imp])[0], grids(looks[want_force])[1], grids(looks[want_amp])[2])
        assert got.duration_s == looks[3].duration_s and got.release == looks[3].release
        assert ctx.parts.frozen_at == {k: v + 1 for k, v in (("impulse", want_imp), ("force", want_force),
                                                             (potential.AMPLITUDE_PART, want_amp)) if v < 3}
    quick = potential.stages(True)
    ctx = _context_at("potential", True, {impulse: 1, amp_impulse: 1})
    assert grids(potential.sweep_plan(quick[1], ctx.plan_for("impulse", quick[1]), ctx.plan_for("force", quick[1]),
                                      ctx.plan_for(potential.AMPLITUDE_PART, quick[1]))) == grids(quick[0])
    for p in (*looks, *quick):  # the default beta's runs at the other betas' starts are in the impulse grid
        assert set(p.amplitude_dphi) <= set(p.impulse_dphi) and set(p.amplitude_phi0) <= set(p.impulse_phi0)
