"""The explanations' protocol: one module per cause, each a CaseExplanation that names only case ids the
sensitivity study makes, reads only the cases it declares, and fails loudly on any other."""

from __future__ import annotations

import importlib
import math
import pkgutil

import numpy as np
import pytest
import xarray as xr

from undulate.studies import _explanations as X
from undulate.studies import describe
from undulate.studies import sensitivity as S
from undulate.studies._explanations import CaseExplanation, CaseResults, results_by_case
from undulate.studies._protocol import Explanation
from undulate.studies._sensitivity_design import (
    CaseId,
    CaseSet,
    UnknownCaseError,
    known_cases,
    pair_cases,
    plan,
    planned_cases,
)


def _modules():
    return [importlib.import_module(f"{X.__name__}.{m.name}") for m in pkgutil.iter_modules(X.__path__)
            if not m.name.startswith("_")]


def test_every_explanation_module_follows_the_protocol_and_is_registered():
    mods = _modules()
    assert len(mods) >= 6 and set(mods) == set(X.MODULES)  # no module forgotten in MODULES
    for m in mods:
        assert isinstance(m.EXPLANATIONS, tuple) and m.EXPLANATIONS, m.__name__
        for e in m.EXPLANATIONS:
            assert isinstance(e, CaseExplanation) and isinstance(e, Explanation)
            assert e.study and e.claim and e.cause and e.cases and callable(e.check)
            assert all(isinstance(c, CaseId) for c in e.cases)
    assert X.EXPLANATIONS == tuple(e for m in X.MODULES for e in m.EXPLANATIONS)
    assert describe("sensitivity").explanations == X.EXPLANATIONS == S.EXPLANATIONS


@pytest.mark.parametrize("quick", [True, False])
def test_explanations_name_only_cases_the_plan_makes(quick):
    made = set(planned_cases(plan(quick)))
    for e in X.EXPLANATIONS:
        assert set(e.cases) <= made, (e.claim, [str(c) for c in set(e.cases) - made])


@pytest.mark.parametrize("quick", [True, False])
def test_case_ids_are_unique_and_round_trip_through_text(quick):
    ids = planned_cases(plan(quick))
    assert len(set(ids)) == len(ids)
    assert all(CaseId.parse(str(c)) == c for c in ids)
    assert {c.case_set for c in ids} == set(CaseSet)


def test_unknown_case_ids_fail_loudly():
    with pytest.raises(UnknownCaseError, match="case set"):
        CaseId.of("xi2", n_links=3)
    with pytest.raises(UnknownCaseError, match="factor"):
        CaseId.of(CaseSet.XI32, n_link=8)  # a typo
    with pytest.raises(UnknownCaseError):
        CaseId.parse("N = 8, 30 s")  # a display label is not an id
    ghost = CaseId.of(CaseSet.XI32, n_links=5, duration_s=30.0)  # well formed, but never made
    assert ghost not in known_cases()
    with pytest.raises(UnknownCaseError, match="does not make"):
        CaseExplanation(study="pairs", claim="c", cause="because", cases=(ghost,), judge=lambda r: (True, "", None))
    declared = X.xi32.N3
    r = CaseResults({"cases": {}}, (declared,))
    assert r.get(declared) is None  # declared, no result in this summary
    with pytest.raises(UnknownCaseError, match="not among"):
        r.get(X.xi32.N8)  # made by the study, but not declared by this reader
    with pytest.raises(UnknownCaseError):
        r.link_set(CaseSet.LINKS)


def _synthetic_dataset(p) -> xr.Dataset:
    """A sensitivity-shaped dataset for plan ``p`` with made-up numbers (no simulation): every case id
    the study's dataset has, from its own case lists."""
    rng = np.random.default_rng(1)
    ids, dphi = pair_cases(p), np.asarray(p.dphi_rad)
    line = dphi / (2 * np.pi)
    dx = line + 0.01 * rng.standard_normal((len(ids), dphi.size))
    groups = S.group_cases()
    g_dphi = np.tile(np.linspace(-0.8 * np.pi, 0.8 * np.pi, 9), (len(groups), 1))
    g_dx = g_dphi / (2 * np.pi) + 0.02 * rng.standard_normal(g_dphi.shape)
    idphi, phi0, drags = np.asarray(p.impulse_dphi_rad), np.asarray(p.impulse_phi0_rad), S.impulse_drags()
    imp = np.abs(idphi)[None, :, None] + 0.1 + 0.01 * rng.random((len(drags), idphi.size, phi0.size))
    readings, ratios = list(S.D_READINGS), [0.9, 1.2, 1.4]
    gd = ("group_case", "neighbour")
    return xr.Dataset(
        {"dx_final_over_lambda": (("case", "dphi"), dx), "residual_over_lambda": (("case", "dphi"), dx - line),
         "steady": (("case", "dphi"), np.ones(dx.shape, bool)),
         "n_links": ("case", [dict(c.levels).get("n_links", 3) for c in ids]),
         "joint_amplitude": ("case", np.full(len(ids), math.pi / 4)), "amplitude": ("case", np.full(len(ids), 0.05)),
         "wavelength": ("case", np.full(len(ids), 0.54)), "is_default": ("case", np.zeros(len(ids), bool)),
         "conf_dx_final_over_lambda": (("d_reading", "d_over_2A", "dx0"),
                                       rng.uniform(-0.05, 0.05, (2, len(ratios), len(p.confinement_starts)))),
         "impulse": ("impulse_dphi", imp[1].mean(axis=1)), "impulse_drag_all": (("impulse_drag", "impulse_dphi", "phi0"), imp),
         "impulse_drag_escape": (("impulse_drag", "impulse_dphi", "phi0"), 0.1 * imp),
         "group_dphi": (gd, g_dphi), "group_dx_over_lambda": (gd, g_dx),
         "group_residual_over_lambda": (gd, g_dx - g_dphi / (2 * np.pi)), "group_dy": (gd, np.full(g_dx.shape, 0.03)),
         "group_band_excess": (gd, np.zeros(g_dx.shape)),
         "group_run": (gd, np.broadcast_to(np.arange(g_dx.shape[-1], dtype=float), g_dx.shape).copy()), "swim_drag_pair_speed": ("dphi", np.full(dphi.size, 3e-3)),
         "amplitude_3_links": ((), 0.05)},
        coords={"case_id": ("case", [str(c) for c in ids]), "claim": ("case", [c.case_set.value for c in ids]),
                "factor": ("case", ["factor"] * len(ids)), "level": ("case", [str(c) for c in ids]), "dphi": dphi,
                "d_reading": readings, "d_over_2A": ratios, "dx0": list(p.confinement_starts),
                "impulse_drag": list(drags), "impulse_dphi": idphi, "phi0": phi0,
                "group_size": ("group_case", [g[0] for g in groups]),
                "group_channel_width": ("group_case", [g[1] for g in groups]),
                "group_default": ("group_case", [g[2] for g in groups])})


def test_the_summary_keys_every_planned_case_by_id_and_every_explanation_reads_it():
    """The study's own summary of a synthetic dataset holds exactly the planned case ids (so the
    explanations' cases, a subset, are found), and every check runs on it by id alone."""
    p = plan(True)
    s = S.summary(_synthetic_dataset(p))
    assert set(results_by_case(s)) == set(planned_cases(p))
    assert set(s["links_sets"]) == {CaseSet.LINKS.value, CaseSet.LINKS_X.value, CaseSet.LINKS_GUIDED.value,
                                    CaseSet.LINKS_GUIDED_X.value}
    for e in X.EXPLANATIONS:
        shown, measured, value = e.check(s)
        assert shown in (True, False, None) and measured and value is not None, e.claim
        # with no results, each reports "not shown" (its cases are declared, merely absent)
        assert e.check({})[0] is False and e.check({})[2] is None


def test_display_labels_do_not_find_cases():
    """Relabelling every case (the table's and the figure's text) changes no explanation's outcome."""
    ds = _synthetic_dataset(plan(True))
    a = S.summary(ds)
    b = S.summary(ds.assign_coords(level=("case", [f"relabelled {i}" for i in range(ds.sizes["case"])]),
                                   factor=("case", ["other"] * ds.sizes["case"])))
    for e in X.EXPLANATIONS:
        assert e.check(a) == e.check(b)


# ---- one change: an explanation names exactly one; several together are a finding ----------------
def _judge(r):
    return True, "", None


def test_an_explanation_of_several_changes_together_is_refused():
    from undulate.studies._explanations._protocol import MultipleChangesError

    case = (X.xi32.N3,)
    one = CaseExplanation(study="pairs", claim="c", cause="because", changes=("N = 3 -> 8 links",), cases=case,
                          judge=_judge)
    assert one.changes == ("N = 3 -> 8 links",) and not one.finding
    with pytest.raises(MultipleChangesError, match="2 changes"):
        CaseExplanation(study="pairs", claim="c", cause="because", changes=("a heading guide", "lambda_x"),
                        cases=case, judge=_judge)
    for bad in (None, (), "one change as a bare string", ("",)):
        with pytest.raises(MultipleChangesError):
            CaseExplanation(study="pairs", claim="c", cause="because", changes=bad, cases=case, judge=_judge)
    # several changes together are a finding: accepted, and marked so
    f = X.CaseFinding(study="pairs", claim="c", cause="because", changes=("a heading guide", "lambda_x"),
                      cases=case, judge=_judge)
    assert f.finding and len(f.changes) == 2
    with pytest.raises(MultipleChangesError):
        X.CaseFinding(study="pairs", claim="c", cause="because", changes=("a",), cases=case, judge=_judge,
                      finding=False)


def test_every_explanation_names_one_change_and_links_is_a_finding():
    for e in X.EXPLANATIONS:
        assert e.finding or len(e.changes) == 1, (e.claim, e.changes)
    links = [e for e in X.EXPLANATIONS if e.study == "links"]
    assert len(links) == 2 and all(isinstance(e, X.CaseFinding) and e.finding for e in links)
    assert all(len(e.changes) >= 2 and e.cause.startswith("Finding, not an explanation") for e in links)
    assert [e for e in X.EXPLANATIONS if not e.finding]  # the one-change explanations stay explanations
    from undulate.studies._protocol import explain

    skipped = [str(c) for e in X.EXPLANATIONS for c in e.cases]  # not run: the checks return at once
    rows = explain("sensitivity", X.EXPLANATIONS, {"cases": {}, "skipped_cases": skipped})
    assert [r["finding"] for r in rows] == [e.finding for e in X.EXPLANATIONS]
