"""A study written exactly as docs/guide/studies.md teaches, with only its five parts (``plan``,
``dataset``, ``summary``, ``CLAIMS``, ``figure``), runs staged through :func:`run_study` in quick and
full mode and gets its verdicts: the registry makes its looks from the plan's ``staged()`` grid, runs a
look only while a claim is undecided, and the study never sees looks, devices or workers.

The study is tiny: pairs of 3-link swimmers (xi = 1) in the pair channel for two gait periods (4 s) at a
few |dphi|, and the paper's claim that the contact impulse over the first two periods grows with |dphi|
(Sec. III.G, Fig. 10a), judged on the slope of a straight line through the impulses.
"""

from __future__ import annotations

import functools
import importlib.util
import json
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from undulate import stats
from undulate.studies import Claim, Study, StudyContext, Verdict, register, run_study, staged
from undulate.studies._criteria import PAIR_CHANNEL_M
from undulate.studies._runners import pair_point
from undulate.sweep import Grid

NAME = "_template_impulse"


# ---- 1. the plan: what is run, in SI units; the grid the looks grow is staged() ----
@dataclass(frozen=True)
class Plan:
    """Pairs at every ``dphi_rad`` (rad, the phase difference) for ``duration_s`` (s)."""

    dphi_rad: tuple[float, ...] = staged()
    duration_s: float = 4.0


def plan(quick: bool) -> Plan:
    """Quick: 5 |dphi| over [0, pi] (looks of 3 and 5); full: 9 (looks of 3, 5 and 9)."""
    return Plan(tuple(float(v) for v in np.linspace(0.0, np.pi, 5 if quick else 9)))


# ---- 2. the dataset: runs through the context, one Dataset with units ----
def dataset(ctx: StudyContext, p: Plan) -> xr.Dataset:
    fn = functools.partial(pair_point, duration_s=p.duration_s)
    sim = ctx.sweep("impulse", fn, Grid(axes={"dphi_rad": list(p.dphi_rad)}, seed=ctx.seed)).isel(replicate=0)
    return xr.Dataset(
        {"impulse": ("dphi", sim["impulse_2T_Ns"].values,
                     {"units": "N s", "long_name": "pair contact impulse over the first two periods"}),
         "run_failed": ("dphi", sim["run_failed"].values.astype(bool))},
        coords={"dphi": ("dphi", np.asarray(p.dphi_rad), {"units": "rad", "long_name": "phase difference"})})


# ---- 3. the summary: pure, every number with its interval ----
def summary(ds: xr.Dataset) -> dict:
    fit = stats.line_fit(np.abs(ds["dphi"].values), ds["impulse"].values)
    return {"slope_Ns_per_rad": fit.slope.to_dict(), "n_runs": int(ds.sizes["dphi"]),
            "n_failed": int(ds["run_failed"].values.sum())}


# ---- 4. the claims: pure functions of the summary ----
def _grows(s: dict) -> Verdict:
    slope = stats.Estimate.from_dict(s["slope_Ns_per_rad"])
    measured = f"slope {slope:.3g} N s/rad over {s['n_runs']} runs ({stats.interval_note(slope.level)})"
    if not slope.has_interval:
        return Verdict.none("no interval for the slope", measured, s["slope_Ns_per_rad"])
    return Verdict.of([slope.above(0.0, "slope of impulse against |dphi|")], measured, s["slope_Ns_per_rad"])


CLAIMS = (
    Claim("the contact impulse over the first two periods grows with |dphi|",
          "the contact force over the first two periods grows with the phase difference",
          "the 95 % t interval of the slope of a line through the impulses against |dphi| lies above 0",
          _grows, where="Sec. III.G, Fig. 10a"),
)


# ---- 5. the figure: from the dataset alone ----
def figure(ds: xr.Dataset):
    from undulate.plotting import new_figure

    fig = new_figure(4.0, 3.0)
    ax = fig.add_subplot()
    ax.plot(np.abs(ds["dphi"].values), ds["impulse"].values, "o")
    ax.set_xlabel(r"$|\Delta\phi|$ (rad)")
    ax.set_ylabel("impulse (N s)")
    return fig


@pytest.fixture
def template_study():
    from undulate.studies import _registry

    _registry._load()
    register(Study(name=NAME, description="the guide's template: contact impulse against |dphi|", plan=plan,
                   dataset=dataset, summary=summary, claims=CLAIMS, figure=figure))
    yield sys.modules[__name__]
    _registry._REGISTRY.pop(NAME, None)


@pytest.mark.parametrize("quick, looks", [(True, (3, 5)), (False, (3, 5, 9))])
def test_a_study_of_five_parts_runs_staged_to_its_verdicts(tmp_path, template_study, quick, looks):
    from undulate.studies import describe
    from undulate.studies._protocol import VERDICTS
    from undulate.studies._staging import stage_plans

    info = describe(NAME)
    assert info.stages is None  # five parts only: the looks come from the plan's staged() grid
    assert tuple(len(p.dphi_rad) for p in stage_plans(info, quick)) == looks
    run_study(NAME, tmp_path, quick=quick, workers=1, progress=False)
    doc = json.loads((tmp_path / f"{NAME}.json").read_text())
    (claim,) = doc["claims"]
    assert claim["verdict"] in VERDICTS
    ran = doc["stages"]
    assert 1 <= len(ran) <= len(looks) and [s["of"] for s in ran] == [len(looks)] * len(ran)
    assert [s["n_runs"] for s in ran] == list(looks[:len(ran)])  # each look runs its own grid, the last reused
    assert doc["n_computed"] == looks[len(ran) - 1] and doc["n_failed"] == 0
    for s in ran[:-1]:  # a look is added only while the claim is open
        assert s["undecided"] == [claim["claim"]]
    if claim["verdict"] in ("holds", "fails"):
        assert claim["decided_at"]["stage"] == len(ran)
    assert doc["summary"]["n_runs"] == looks[len(ran) - 1]


GUIDE = Path(__file__).resolve().parents[1] / "docs" / "guide" / "studies.md"


def test_the_guides_own_study_runs_staged_as_written(tmp_path):
    """The study printed in docs/guide/studies.md ("Adding a study"), copied into a file as a reader
    would, registers on import and runs staged in quick mode to its verdict."""
    from undulate.studies import _registry, describe
    from undulate.studies._protocol import VERDICTS
    from undulate.studies._staging import stage_plans

    section = GUIDE.read_text(encoding="utf-8").split("## Adding a study", 1)[1]
    code = re.search(r"^```python\n(.*?)^```", section, re.S | re.M).group(1)
    path = tmp_path / "guide_study.py"
    path.write_text(code)
    _registry._load()
    spec = importlib.util.spec_from_file_location("guide_study", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["guide_study"] = module
    try:
        spec.loader.exec_module(module)  # registers "impulse"
        info = describe("impulse")
        assert info.stages is None and [len(p.dphi_rad) for p in stage_plans(info, True)] == [3, 5]
        run_study("impulse", tmp_path / "out", quick=True, workers=1, progress=False)
        doc = json.loads((tmp_path / "out" / "impulse.json").read_text())
        assert doc["claims"][0]["verdict"] in VERDICTS and doc["n_failed"] == 0
        assert [s["n_runs"] for s in doc["stages"]] == [3, 5][:len(doc["stages"])]
    finally:
        _registry._REGISTRY.pop("impulse", None)
        sys.modules.pop("guide_study", None)


def test_a_cap_on_looks_runs_fewer_and_judges_at_that_many_looks_level(tmp_path, template_study):
    """``max_looks=1`` on full mode's three looks: one look of 3 runs, judged at the level of a plan of one
    look (95 %, not the 99.5 % its first look of three has), recorded in the JSON and the identity; the same
    study without the cap is not taken for it, and reuses the capped look's runs."""
    from undulate import stats
    from undulate.studies import StudyConfig, is_current

    run_study(NAME, tmp_path, quick=False, workers=1, progress=False, max_looks=1)
    doc = json.loads((tmp_path / f"{NAME}.json").read_text())
    (look,) = doc["stages"]
    assert look["of"] == 1 and look["n_runs"] == 3 and doc["n_computed"] == 3
    assert look["confidence_level"] == pytest.approx(stats.look_levels(1)[0]) == pytest.approx(0.95)
    assert doc["config"]["max_looks"] == 1 and doc["identity"]["max_looks"] == 1
    assert is_current(NAME, StudyConfig(out_dir=tmp_path, quick=False, max_looks=1))
    assert not is_current(NAME, StudyConfig(out_dir=tmp_path, quick=False))
    run_study(NAME, tmp_path, quick=False, workers=1, progress=False)
    doc = json.loads((tmp_path / f"{NAME}.json").read_text())
    assert "max_looks" not in doc["identity"] and doc["config"]["max_looks"] is None
    assert doc["stages"][0]["of"] == 3 and doc["stages"][0]["n_computed"] == 0  # the capped look's runs, reused


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_a_cap_on_looks_is_an_integer_of_at_least_one(tmp_path, bad):
    from undulate.errors import ParameterError
    from undulate.studies import StudyConfig

    with pytest.raises(ParameterError, match="max_looks"):
        StudyConfig(out_dir=tmp_path, max_looks=bad)


def test_a_reproduction_with_a_cap_on_looks_says_so_and_keeps_its_results_apart(tmp_path, template_study):
    """``reproduce(max_looks=1)``: the page's mode names the cap; rerun with the cap it keeps the study, rerun
    without it runs the study again (its identity differs)."""
    from undulate.reproduce import reproduce

    logs: list[str] = []
    path, statuses = reproduce(tmp_path, quick=False, studies=[NAME], log=logs.append, animation_s=0.5,
                               workers=1, max_looks=1)
    assert statuses[0]["ok"] and "Mode: <b>full, at most 1 look a study</b>" in path.read_text()
    assert any("running (full, at most 1 look a study)" in m for m in logs)
    logs.clear()
    reproduce(tmp_path, quick=False, studies=[NAME], log=logs.append, animation_s=0.5, workers=1, max_looks=1)
    assert any(f"{NAME}: done earlier" in m for m in logs)
    logs.clear()
    _, statuses = reproduce(tmp_path, quick=False, studies=[NAME], log=logs.append, animation_s=0.5, workers=1)
    assert not statuses[0]["reused"] and any("running (full)" in m for m in logs)
    assert "Mode: <b>full</b>" in path.read_text()
