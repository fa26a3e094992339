"""The sensitivity study runs a factor group only for an explanation that is needed (the claim it explains
fails, or its verdict is unknown); a skipped group is NaN rows made without a run, its table rows read
``no result`` and its explanations are not judged (shown None).  No simulation runs here."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from undulate.studies import sensitivity as S
from undulate.studies._explanations import EXPLANATIONS, MODULES
from undulate.studies._explanations import groups as XG
from undulate.studies._explanations import impulse as XI
from undulate.studies._explanations._protocol import NOT_RUN
from undulate.studies._context import StudyContext
from undulate.studies._protocol import NO_RESULT, explain
from undulate.studies._registry import describe
from undulate.studies._staging import part_plans, stage_plans
from undulate.studies._sensitivity_design import CaseSet, pair_cases, plan, planned_cases

A3 = 0.05


class FakeContext:
    """Records every sweep and lone swimmer asked for; answers the default lone swimmer only."""

    name = "sensitivity"

    def __init__(self, not_needed: set[str], quick: bool = True, decided: dict | None = None):
        self.not_needed = not_needed  # explanation studies whose claims hold
        self.calls: list[tuple] = []
        self.seed = 0
        # the staging engine's parts at a look after ``decided`` ((study, claim) -> the look that decided it)
        self.parts = _parts(quick, self.needs_explanation, decided or {})

    plan_for = StudyContext.plan_for

    def needs_explanation(self, study: str, claim: str) -> bool:
        return study not in self.not_needed

    def sweep(self, part, *args, **kw):
        self.calls.append(("sweep", part))
        raise AssertionError(f"sweep {part} ran")

    def shared_sweep(self, part, *args, **kw):
        self.calls.append(("shared_sweep", part))
        raise AssertionError(f"shared sweep {part} ran")

    def together(self, *calls):  # StudyContext.together on the MuJoCo backend: one after another
        return [call() for call in calls]

    def lone_swimmer(self, **kw):
        self.calls.append(("lone_swimmer", tuple(sorted(kw.items()))))
        if kw:
            raise AssertionError(f"lone swimmer {kw} ran")
        return {"amplitude_m": A3}


def _parts(quick, needs, decided=None):
    info = describe("sensitivity")
    return part_plans(info, stage_plans(info, quick), {}, decided or {}, needs)


def _needed(needs, explanations=EXPLANATIONS) -> frozenset[str]:
    """The factor groups some needed explanation reads (the parts the engine runs)."""
    return frozenset(g for e in explanations if needs(e.study, e.claim) for g in e.reads)


def _xi1_nan(r):
    """The xi = 1 steps (always run) without their runs: their cases as NaN rows."""
    return [r.case(c, "f", str(c), r.nan_rows()) for c in pair_cases(r.p) if c.case_set is CaseSet.XI1]


def _stub_running_groups(monkeypatch):
    """Stub the steps that would run here (xi = 1 and the needed groups) so that no simulation runs; the
    skipped groups' steps stay the real ones."""
    import dataclasses

    monkeypatch.setattr(S, "_data_xi1_model", lambda r: _xi1_nan(r)[:len(S.MODEL_LEVELS)])
    monkeypatch.setattr(S, "_data_xi1_windows", lambda r: _xi1_nan(r)[len(S.MODEL_LEVELS):])
    everything = frozenset(S.SKIPPABLE_GROUPS)
    for name in ("_data_xi32", "_data_links_equal_a", "_data_links_guided", "_data_confinement",
                 "_data_groups", "_data_swimming", "_data_impulse"):
        real = getattr(S, name)
        # a needed group: its real step on a copy told every group is skipped (NaN, no run)
        monkeypatch.setattr(S, name, lambda r, real=real: real(r) if _skipped_here(real, r)
                            else real(dataclasses.replace(r, skipped=everything)))


_GROUP_OF_STEP = {"_data_xi32": "xi32", "_data_links_equal_a": "links", "_data_links_guided": "links",
                  "_data_confinement": "confinement", "_data_groups": "groups", "_data_swimming": "swimming",
                  "_data_impulse": "impulse"}


def _skipped_here(step, r) -> bool:
    return _GROUP_OF_STEP[step.__name__] in r.skipped


def test_the_groups_each_explanation_module_needs():
    """Which factor groups each explanation module's cases come from (its declared cases)."""
    expected = {"xi32": {"xi32"}, "links": {"links"}, "confinement": {"confinement"}, "groups": {"groups"},
                "swimming": {"swimming"}, "impulse": {"impulse"}}
    for m in MODULES:
        got = _needed(lambda study, claim: True, m.EXPLANATIONS)
        assert got == expected[m.__name__.rsplit(".", 1)[1]], m.__name__
    assert _needed(lambda study, claim: True) == frozenset(S.SKIPPABLE_GROUPS)
    assert _needed(lambda study, claim: False) == frozenset()
    assert _parts(True, lambda study, claim: False).not_run == frozenset(S.SKIPPABLE_GROUPS)
    # every case the study makes, but the xi = 1 ones, belongs to a skippable group
    for quick in (True, False):
        for c in planned_cases(plan(quick)):
            assert (c.case_set in S.FACTOR_GROUPS) == (c.case_set is not CaseSet.XI1)


def test_needed_groups_follow_the_claims_that_fail():
    holds = {("groups", e.claim) for e in XG.EXPLANATIONS} | {("potential", e.claim) for e in XI.EXPLANATIONS}
    got = _parts(True, lambda study, claim: (study, claim) not in holds).not_run
    assert got == {"groups", "impulse"}
    # one of the two groups claims failing is enough to run the groups
    one = _parts(True, lambda study, claim: claim == XG.EXPLANATIONS[1].claim).not_run
    assert one == frozenset(S.SKIPPABLE_GROUPS) - {"groups"}


def test_skipped_groups_run_nothing_and_keep_their_cases(monkeypatch):
    _stub_running_groups(monkeypatch)
    ctx = FakeContext(not_needed={"groups", "potential"})
    p = plan(True)
    ds = S.dataset(ctx, p)
    assert ctx.calls == [("lone_swimmer", ())]  # the stubs stand for the needed groups' runs
    assert json.loads(ds.attrs["skipped_factor_groups"]) == ["groups", "impulse"]
    assert list(ds["case_id"].values) == [str(c) for c in pair_cases(p)]
    assert ds["impulse_drag_all"].shape == (len(ds["impulse_drag"]), len(p.impulse_dphi_rad),
                                            len(p.impulse_phi0_rad))
    assert np.isnan(ds["impulse"].values).all() and np.isnan(ds["group_dx_over_lambda"].values).all()
    assert ds.sizes["group_case"] == 5
    assert ds.sizes["neighbour"] == 3 * p.group_draws  # four swimmers: 3 neighbour pairs per draw


def test_a_fully_skipped_study_summarises_without_claims(monkeypatch):
    import warnings

    _stub_running_groups(monkeypatch)
    ctx = FakeContext(not_needed={e.study for e in EXPLANATIONS})
    p = plan(True)
    ds = S.dataset(ctx, p)
    assert ctx.calls == [("lone_swimmer", ())]
    assert json.loads(ds.attrs["skipped_factor_groups"]) == list(S.SKIPPABLE_GROUPS)
    assert ds["conf_dx_over_lambda"].shape[-1] == ds.sizes["time"] > 1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        s = S.summary(ds)
    assert s["skipped_factor_groups"] == list(S.SKIPPABLE_GROUPS)
    assert s["skipped_cases"] and all("xi1" not in c for c in s["skipped_cases"])
    for t in s["table"]:
        if t["claim"] != S.CLAIM_LABELS["xi1"]:
            assert t["verdict"] == NO_RESULT and t["reason"] == S.NOT_RUN, t
    rows = explain("sensitivity", EXPLANATIONS, s)
    assert len(rows) == len(EXPLANATIONS)
    for row in rows:
        assert row["shown"] is None and row["measured"] == NOT_RUN and row["value"] is None, row
    # the figure draws NaN groups
    import matplotlib

    matplotlib.use("Agg")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fig = S.figure(ds)
    assert fig is not None


def test_a_skipped_group_is_not_run_even_where_its_nan_rows_would_refute():
    """The confinement judge reads NaN widths as 'not closed in range' (False); a skipped group must give
    None with the not-run text, not False."""
    from undulate.studies._explanations import confinement as XC

    d = {"case_id": str(XC.DEFAULT_READING), "body_width_m": 0.015, "d_over_2A": [0.9, 1.2],
         "channel_width_m": [0.188, 0.251], "central_width_over_lambda": [math.nan, math.nan],
         "model_opening_d_over_2A": 0.64, "broadens_centreline_A": None}
    t = {**d, "case_id": str(XC.WHOLE), "channel_width_m": [0.094, 0.125], "model_opening_d_over_2A": 1.29}
    summary = {"confinement": {"per-swimmer": d, "whole-width": t}}
    e = XC.EXPLANATIONS[0]
    assert e.check(summary)[0] is False  # what NaN rows alone would say
    summary["skipped_cases"] = [str(XC.DEFAULT_READING), str(XC.WHOLE)]
    assert e.check(summary) == (None, NOT_RUN, None)


@pytest.mark.parametrize("group", S.SKIPPABLE_GROUPS)
def test_each_group_marks_only_its_rows(group, monkeypatch):
    _stub_running_groups(monkeypatch)
    not_needed = {e.study for e in EXPLANATIONS if set(e.reads) == {group}}
    ds = S.dataset(FakeContext(not_needed=not_needed), plan(True))
    assert json.loads(ds.attrs["skipped_factor_groups"]) == [group]
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        s = S.summary(ds)
    rows = explain("sensitivity", EXPLANATIONS, s)
    for e, row in zip(EXPLANATIONS, rows):
        mine = set(e.reads) == {group}
        assert (row["measured"] == NOT_RUN) == mine, (group, e.claim)
        if mine:
            assert row["shown"] is None
    assert any(t.get("reason") == S.NOT_RUN for t in s["table"])


def test_frozen_groups_are_those_whose_needed_explanations_are_all_decided():
    from undulate.studies._explanations import links as XL
    from undulate.studies._explanations import xi32 as X32

    every = lambda study, claim: True  # noqa: E731

    def frozen_groups(needs, decided):
        return _parts(False, needs, decided).frozen_at

    links_at = {(e.study, e.claim): 1 for e in XL.EXPLANATIONS}
    assert frozen_groups(every, {}) == {}
    assert frozen_groups(every, links_at) == {"links": 1}
    # one of the two links explanations still open: the group runs on
    assert frozen_groups(every, dict(list(links_at.items())[:1])) == {}
    # decided at different looks: the latest look's plan
    later = {**links_at, (XL.EXPLANATIONS[1].study, XL.EXPLANATIONS[1].claim): 2,
             **{(e.study, e.claim): 1 for e in X32.EXPLANATIONS}}
    assert frozen_groups(every, later) == {"links": 2, "xi32": 1}
    # a group no needed explanation reads is skipped, not frozen
    assert frozen_groups(lambda study, claim: study != "links", links_at) == {}
    assert _parts(False, lambda study, claim: study != "links", links_at).not_run == {"links"}


@pytest.mark.parametrize("decided", [False, True])
def test_a_frozen_group_keeps_the_plan_of_the_look_that_decided_it(decided, monkeypatch):
    """Full mode's second look with the links explanations decided at the first: the links steps run on
    the first look's plan (its dphi: runs already made), and their cases sit on the second look's dphi
    axis with NaN where the first look ran nothing; undecided, they run on the second look's plan."""
    from undulate.studies._explanations import links as XL

    _stub_running_groups(monkeypatch)
    seen = []

    def links_step(r):  # every links case, in pair_cases order, rows of ones on the runs' dphi
        seen.append(np.asarray(r.dphis))
        return [r.case(c, "f", str(c), np.ones((len(r.dphis), 3)))
                for c in pair_cases(r.p) if S.FACTOR_GROUPS.get(c.case_set) == "links"]

    monkeypatch.setattr(S, "_data_links_equal_a", links_step)
    monkeypatch.setattr(S, "_data_links_guided", lambda r: [])
    first, second = S.stages(False)[:2]
    assert len(second.dphi_rad) > len(first.dphi_rad)
    ctx = FakeContext(not_needed={e.study for e in EXPLANATIONS} - {"links"}, quick=False,
                      decided={(e.study, e.claim): 1 for e in XL.EXPLANATIONS} if decided else None)
    ds = S.dataset(ctx, second)
    assert list(ds["case_id"].values) == [str(c) for c in pair_cases(second)]
    (ran,) = seen
    np.testing.assert_array_equal(ran, first.dphi_rad if decided else second.dphi_rad)
    assert ctx.parts.frozen_at == ({"links": 1} if decided else {})
    is_links = [S.FACTOR_GROUPS.get(CaseSet(str(c))) == "links" for c in ds["claim"].values]
    y = ds["dx_final_over_lambda"].values[is_links]
    ran_here = np.isin(ds["dphi"].values, first.dphi_rad) if decided else np.ones(ds.sizes["dphi"], bool)
    assert (y[:, ran_here] == 1.0).all() and np.isnan(y[:, ~ran_here]).all()


def test_the_xi1_cases_stay_on_their_phases_while_an_open_group_runs_the_cap(monkeypatch):
    """Full mode's third look (33 pair phases, the cap sized for the swimming explanation): the swimming
    step runs all 33, the xi = 1 steps (the table's only) their 17, bitwise the second look's, and their
    cases sit on the 33's axis with NaN at the 16 phases they did not run."""
    _stub_running_groups(monkeypatch)
    seen = {}

    def xi1_step(r, part):
        seen.setdefault("xi1", []).append(np.asarray(r.dphis))
        cases = [r.case(c, "f", str(c), np.ones((len(r.dphis), 3))) for c in pair_cases(r.p)
                 if c.case_set is CaseSet.XI1]
        return cases[:len(S.MODEL_LEVELS)] if part == 0 else cases[len(S.MODEL_LEVELS):]

    monkeypatch.setattr(S, "_data_xi1_model", lambda r: xi1_step(r, 0))
    monkeypatch.setattr(S, "_data_xi1_windows", lambda r: xi1_step(r, 1))
    real_swim = S._data_swimming

    def swim_step(r):
        seen["swimming"] = np.asarray(r.dphis)
        return real_swim(dataclasses.replace(r, skipped=frozenset(S.SKIPPABLE_GROUPS)))

    monkeypatch.setattr(S, "_data_swimming", swim_step)
    second, third = S.stages(False)[1:]
    assert (len(second.dphi_rad), len(third.dphi_rad), len(third.xi1_phases)) == (17, 33, 17)
    ctx = FakeContext(not_needed={e.study for e in EXPLANATIONS} - {"swimming"}, quick=False)
    ds = S.dataset(ctx, third)
    np.testing.assert_array_equal(seen["swimming"], third.dphi_rad)
    for ran in seen["xi1"]:
        assert ran.tobytes() == np.asarray(second.dphi_rad).tobytes()
    is_xi1 = ds["claim"].values == CaseSet.XI1.value
    y = ds["dx_final_over_lambda"].values[is_xi1]
    on17 = np.isin(ds["dphi"].values, second.dphi_rad)
    assert on17.sum() == 17 and (y[:, on17] == 1.0).all() and np.isnan(y[:, ~on17]).all()


@pytest.mark.parametrize("quick", [True, False])
def test_findings_run_in_full_mode_only(tmp_path, quick):
    """A claim that only findings read (links: its several-change account) needs no runs in quick mode, which
    runs what decides verdicts: a finding never changes one.  Full mode runs it when the claim fails (here
    its verdict is unknown: the study alone); an explanation proper (xi = 3/2) is needed in both modes."""
    from undulate.studies import StudyConfig

    ctx = StudyContext(StudyConfig(out_dir=tmp_path, quick=quick), "sensitivity", progress=False,
                       explanations=describe("sensitivity").explanations)
    findings = [e for e in EXPLANATIONS if getattr(e, "finding", False)]
    proper = [e for e in EXPLANATIONS if not getattr(e, "finding", False)]
    assert findings and proper
    only_findings = {(e.study, e.claim) for e in findings} - {(e.study, e.claim) for e in proper}
    assert only_findings
    for study, claim in only_findings:
        assert ctx.needs_explanation(study, claim) is (not quick)
    for e in proper:
        assert ctx.needs_explanation(e.study, e.claim) is True
    parts = _parts(quick, ctx.needs_explanation)
    assert ("links" in parts.not_run) is quick  # the links factor group: read by findings only
