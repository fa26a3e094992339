"""Every registered study under the same invariants (as dm_control's suite test does for its tasks).

Fast (default suite): the protocol of every study (plan, dataset, pure summary, claims, figure),
and, on a throwaway study with a real MuJoCo sweep, the store layout: another seed into the
same folder works (``study`` and ``reproduce``), a second run computes nothing, a change of the
code behind a sweep recomputes it.

Slow (``pytest -m slow``, ~25 min on 2 cores): every registered study in quick mode, twice into
one folder and once into another: units on every variable, no claim without a verdict, the
second run computes nothing and gives the same numbers, the fresh run gives identical numbers.
"""

from __future__ import annotations

import functools
import json
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import sweep_funcs  # noqa: E402

from undulate import stats, studies  # noqa: E402
from undulate.reproduce import reproduce  # noqa: E402
from undulate.studies import _registry  # noqa: E402
from undulate.sweep import Grid  # noqa: E402


@pytest.mark.parametrize("name", studies.names())
def test_every_study_states_the_protocol(name):
    info = studies.describe(name)
    assert info.module.startswith("undulate.studies.") and info.description
    for quick in (True, False):
        info.plan(quick)  # both plans exist and need no simulation
    for c in info.claims:
        assert isinstance(c, studies.Claim) and c.claim and c.paper and c.criterion and callable(c.judge)
    assert callable(info.summary) and callable(info.figure)
    if info.needs_simulation:
        assert info.claims or info.explanations, \
            f"{name}: a simulation study judges at least one claim or checks at least one explanation"
    for e in info.explanations:
        assert isinstance(e, studies.Explanation) and e.study and e.claim and e.cause and callable(e.check)


# ---- a cheap real study: a pendulum sweep through the registry --------------------
def _pendulum_dataset(ctx, plan):
    fn = functools.partial(sweep_funcs.pendulum)
    ds = ctx.sweep("swing", fn, Grid(axes={"damping_Nms": [0.1, 0.2], "length_m": [0.5]}, replicates=2,
                                     seed=ctx.config.seed))
    return xr.Dataset({"final_angle": (("damping", "draw"), ds["final_angle"].isel(length_m=0).values,
                                       {"units": "rad"})},
                      coords={"damping": ("damping", [0.1, 0.2], {"units": "N m s/rad"}),
                              "draw": ("draw", [0, 1], {"units": "1"})})


class _Fig:
    def savefig(self, path, **kw):
        Path(path).write_bytes(b"%PDF-1.4 figure" if kw.get("format") == "pdf" else b"\x89PNG\r\n\x1a\n")


@pytest.fixture
def pendulum_study():
    info = studies.register(studies.Study(
        name="_pendulum", description="test: damped pendulum", plan=lambda quick: None,
        dataset=_pendulum_dataset, summary=lambda ds: {"mean_final_angle_rad": float(ds["final_angle"].mean())},
        figure=lambda ds: _Fig()))
    yield info
    _registry._REGISTRY.pop("_pendulum", None)


def test_another_seed_into_the_same_folder_and_a_second_run_that_computes_nothing(tmp_path, pendulum_study):
    studies.run_study("_pendulum", tmp_path, quick=True, seed=0, progress=False)
    first = json.loads((tmp_path / "_pendulum.json").read_text())
    assert first["n_computed"] == 4 and first["sweeps"][0]["code"] and first["identity"]["seed"] == 0
    studies.run_study("_pendulum", tmp_path, quick=True, seed=0, progress=False)
    again = json.loads((tmp_path / "_pendulum.json").read_text())
    assert again["n_computed"] == 0 and again["summary"] == first["summary"]
    # another seed into the same folder: its own store, new draws, no error
    studies.run_study("_pendulum", tmp_path, quick=True, seed=1, progress=False)
    other = json.loads((tmp_path / "_pendulum.json").read_text())
    assert other["n_computed"] == 4 and other["identity"]["seed"] == 1
    assert other["summary"] != first["summary"]
    assert sorted(p.name for p in (tmp_path / ".sweeps" / "_pendulum").iterdir()) == [
        "swing-quick-seed0", "swing-quick-seed1"]
    ds = xr.load_dataset(tmp_path / "_pendulum.nc", engine="h5netcdf")
    assert json.loads(ds.attrs["study_sweeps"])[0]["code"] == other["sweeps"][0]["code"]


@pytest.mark.slow  # ~17 s; another seed into the same folder stays in the default run
def test_reproduce_with_another_seed_recomputes_the_study(tmp_path, pendulum_study):
    logs: list[str] = []
    reproduce(tmp_path, quick=True, seed=0, studies=["_pendulum"], log=logs.append, animation_s=0.5)
    s0 = json.loads((tmp_path / "_pendulum.json").read_text())["summary"]
    reproduce(tmp_path, quick=True, seed=0, studies=["_pendulum"], log=logs.append, animation_s=0.5)
    assert any("done earlier" in m for m in logs)
    logs.clear()
    reproduce(tmp_path, quick=True, seed=1, studies=["_pendulum"], log=logs.append, animation_s=0.5)
    assert not any("done earlier" in m for m in logs)
    doc = json.loads((tmp_path / "_pendulum.json").read_text())
    assert doc["identity"]["seed"] == 1 and doc["summary"] != s0
    claims = json.loads((tmp_path / "claims.json").read_text())
    assert claims["claims"] == [] and set(claims["counts"]) == {"holds", "explained", "undecided", "fails", "no result"}


# ---- every registered study in quick mode ------------------------------------------
def _numbers(ds: xr.Dataset) -> dict:
    return {k: v.values for k, v in ds.variables.items() if v.dtype.kind in "biufc"}


@pytest.fixture(scope="module")
def quick_folders(tmp_path_factory):
    """The two folders every study of the slow suite runs into, in the registry's order (a study
    reuses the sweeps an earlier one shares with it, as in a reproduction)."""
    root = tmp_path_factory.mktemp("quick")
    return root / "a", root / "b"


@pytest.mark.slow
@pytest.mark.parametrize("name", studies.names())
def test_every_registered_study_in_quick_mode(name, quick_folders):
    """One study a case (``-k NAME`` runs one alone: it then makes the sweeps it shares itself)."""
    a, b = quick_folders
    studies.run_study(name, a, quick=True, progress=False)
    doc = json.loads((a / f"{name}.json").read_text())
    ds = xr.load_dataset(a / f"{name}.nc", engine="h5netcdf")
    for k, v in ds.variables.items():
        if v.dtype.kind in "iufc":
            assert "units" in v.attrs, (name, k)
    judged = [c for c in doc["claims"] if c["verdict"] in ("holds", "fails", "undecided")]
    # an undecided claim names the boundary its interval straddles (or its intervals straddle: potential's
    # two shares about 1/2), or says it has no interval (a rank correlation of too few orderings:
    # potential's 3 d/2A in quick mode)
    assert all("straddle" in c["reason"] or "overlaps" in c["reason"] or "no interval" in c["reason"]
               for c in judged if c["verdict"] == "undecided"), (name, judged)
    # the one designed "no result": phase-interaction where the measured H is zero at every held dphi
    # (free pairs that stop touching), never for want of runs
    unjudged = [c for c in doc["claims"] if c not in judged]
    assert all(name == "phase-interaction" and c["verdict"] == "no result" and "H is zero" in c["reason"]
               for c in unjudged), (name, unjudged)
    assert doc["n_failed"] == 0 and (judged or not doc["claims"]), (name, doc["claims"])  # compatibility: none
    # no reported number or interval leaves its quantity's physical domain (what claims.collect refuses)
    assert stats.domain_violations({"summary": doc["summary"], "claims": [c["value"] for c in doc["claims"]]}) == []
    # a second run into the same folder computes nothing and gives the same numbers
    studies.run_study(name, a, quick=True, progress=False)
    again = json.loads((a / f"{name}.json").read_text())
    assert again["n_computed"] == 0, (name, again["sweeps"])
    assert again["summary"] == doc["summary"] and again["claims"] == doc["claims"]
    # deterministic: a fresh folder gives identical numbers
    studies.run_study(name, b, quick=True, progress=False)
    fresh = json.loads((b / f"{name}.json").read_text())
    assert fresh["summary"] == doc["summary"], name
    ds_b = xr.load_dataset(b / f"{name}.nc", engine="h5netcdf")
    na, nb = _numbers(ds), _numbers(ds_b)
    assert na.keys() == nb.keys()
    for k in na:
        np.testing.assert_array_equal(na[k], nb[k], err_msg=f"{name}: {k}")
