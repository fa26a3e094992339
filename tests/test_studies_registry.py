"""The study registry: run, write atomically, reopen with units and provenance."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

from undulate import studies
from undulate.errors import ParameterError, UndulateError
from undulate.studies import _registry, _staging


def test_compatibility_is_registered_theory_only():
    assert "compatibility" in studies.names()
    info = studies.describe("compatibility")
    assert info.needs_simulation is False and info.paper_figure == "4"
    assert str(info).startswith(info.description) and "theory only" in str(info)


def test_studies_come_in_the_papers_order():
    """The order of ``undulate studies``, the reproduction and the report: paper figures
    3-10, then the Methods, the studies beyond the paper, and last the explanations (a study added
    by a user takes its place among them: only the package's own are checked)."""
    ours = ["pairs", "compatibility", "links", "groups", "packing", "basins", "confinement", "potential", "swimming",
            "phase-interaction", "synchronization-pairs", "synchronization-groups", "sensitivity"]
    assert [n for n in studies.names() if n in ours] == ours


def test_every_study_module_registers_itself():
    import pkgutil

    modules = {m.name for m in pkgutil.iter_modules(studies.__path__) if not m.name.startswith("_")}
    registered = {studies.describe(n).module.rsplit(".", 1)[-1] for n in studies.names()}
    assert modules == registered
    assert not hasattr(_registry, "STUDY_MODULES")  # no list to edit


def test_adding_a_module_is_the_only_step(tmp_path, monkeypatch):
    (tmp_path / "zz_extra.py").write_text(
        "from undulate.studies import Study, register\n"
        "register(Study(name='zz-late', description='t', needs_simulation=False, plan=lambda q: None,\n"
        "               dataset=lambda c, p: None, summary=lambda ds: {}, figure=lambda ds: None))\n"
        "register(Study(name='zz-early', description='t', needs_simulation=False, plan=lambda q: None,\n"
        "               dataset=lambda c, p: None, summary=lambda ds: {}, figure=lambda ds: None, order=4.5))\n"
        "register(Study(name='zz-fig', description='t', needs_simulation=False, plan=lambda q: None,\n"
        "               dataset=lambda c, p: None, summary=lambda ds: {}, figure=lambda ds: None,\n"
        "               paper_figure='8'))\n")
    import sys

    monkeypatch.setattr(studies, "__path__", [*studies.__path__, str(tmp_path)])
    monkeypatch.setattr(_registry, "_loaded", False)
    try:
        names = studies.names()
        assert studies.describe("zz-late").module == "undulate.studies.zz_extra"
        assert names.index("compatibility") < names.index("zz-early") < names.index("links")  # explicit order
        assert names.index("basins") < names.index("zz-fig") < names.index("confinement")  # figure 8, after basins
        assert names.index("synchronization-groups") < names.index("zz-late") < names.index("sensitivity")
    finally:
        for name in ("zz-late", "zz-early", "zz-fig"):
            _registry._REGISTRY.pop(name, None)
        sys.modules.pop("undulate.studies.zz_extra", None)


def test_unknown_study_names_the_known_ones(tmp_path):
    with pytest.raises(ParameterError, match="compatibility") as err:
        studies.run_study("no-such-study", tmp_path)
    assert err.value.name == "study"
    assert list(tmp_path.iterdir()) == []


def test_compatibility_study_writes_its_files(tmp_path):
    out = tmp_path / "res"
    nc = studies.run_study("compatibility", out, quick=True, seed=3)
    assert nc == out / "compatibility.nc"
    assert sorted(p.name for p in out.iterdir()) == [
        "compatibility.json", "compatibility.nc", "compatibility.pdf", "compatibility.png"]
    assert (out / "compatibility.pdf").read_bytes()[:4] == b"%PDF"
    assert (out / "compatibility.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    with xr.open_dataset(nc, engine="h5netcdf") as ds:
        assert ds["dphi"].attrs["units"] == "rad"
        for name in ("dx_over_lambda", "dy_over_2A", "min_dy_over_2A", "compatible_fraction"):
            assert ds[name].attrs["units"] == "1"
        assert ds["compatible"].dtype == bool
        assert ds.attrs["study"] == "compatibility"
        assert json.loads(ds.attrs["study_config"]) == {
            "out_dir": str(out), "quick": True, "scheduler": None, "seed": 3, "workers": None,
            "max_looks": None}
        assert json.loads(ds.attrs["study_identity"])["seed"] == 3
        for key in ("undulate_version", "mujoco_version", "created_utc", "hostname"):
            assert ds.attrs[key]
        # the physics survives the round trip: the region is the closed form
        P, X, Y = xr.broadcast(ds["dphi"], ds["dx_over_lambda"], ds["dy_over_2A"])
        psi = (P - 2 * np.pi * X + np.pi) % (2 * np.pi) - np.pi
        mismatch = np.abs(psi) - 2 * np.arcsin(np.minimum(Y, 1))
        clear = np.abs(mismatch) > 1e-9
        np.testing.assert_array_equal(ds["compatible"].values[clear], (mismatch <= 0).values[clear])
        assert ds["compatible"].sel(dy_over_2A=0.0).any()  # the equality line itself
        assert ds["compatible"].where(ds["dy_over_2A"] >= 1.0, True).all()

    doc = json.loads((out / "compatibility.json").read_text())
    assert doc["study"] == "compatibility" and doc["provenance"]["undulate_version"]
    for s, sec in doc["summary"]["sections"].items():
        assert sec["compatible_fraction_theory"] == pytest.approx(2 * np.arcsin(float(s)) / np.pi)
        assert sec["compatible_fraction"] == pytest.approx(sec["compatible_fraction_theory"], abs=0.01)
    assert doc["summary"]["smallest_dy_over_2A_all_compatible"] == pytest.approx(1.0)


@pytest.mark.parametrize("name", [n for n in studies.names() if not studies.describe(n).needs_simulation])
def test_every_theory_study_runs_quick(name, tmp_path):
    nc = studies.run_study(name, tmp_path, quick=True)
    assert nc.exists() and (tmp_path / f"{name}.json").exists()


@pytest.fixture
def temporary_study():
    """Register throwaway studies; remove them afterwards."""
    added = []

    def add(name, make_dataset, figure):
        studies.register(studies.Study(
            name=name, description="test", needs_simulation=False, plan=lambda quick: None,
            dataset=lambda ctx, plan: make_dataset(), summary=lambda ds: {}, figure=lambda ds: figure))
        added.append(name)

    yield add
    for name in added:
        _registry._REGISTRY.pop(name, None)


def _tiny_dataset():
    return xr.Dataset({"v": ("x", np.arange(3.0), {"units": "m"})},
                      coords={"x": ("x", np.arange(3), {"units": "1"})})


class _BrokenFigure:
    def savefig(self, path, **kwargs):
        with open(path, "wb") as f:  # half a file, then failure
            f.write(b"%PDF-1.4 partial")
        raise OSError("disk full")


def test_failed_write_leaves_nothing(tmp_path, temporary_study):
    temporary_study("_broken", _tiny_dataset, _BrokenFigure())
    (tmp_path / "_broken.nc").write_bytes(b"old result")  # an earlier run's file survives intact
    with pytest.raises(OSError, match="disk full"):
        studies.run_study("_broken", tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["_broken.nc"]
    assert (tmp_path / "_broken.nc").read_bytes() == b"old result"


def test_variables_without_units_are_refused(tmp_path, temporary_study):
    def make():
        ds = _tiny_dataset()
        ds["w"] = ("x", np.ones(3))
        return ds

    temporary_study("_unitless", make, _BrokenFigure())
    with pytest.raises(UndulateError, match="'w'"):
        studies.run_study("_unitless", tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_a_study_in_another_mode_or_seed_is_not_current(tmp_path):
    studies.run_study("compatibility", tmp_path, quick=True, seed=0)
    cfg = studies.StudyConfig(out_dir=tmp_path, quick=True, seed=0)
    assert studies.is_current("compatibility", cfg)
    assert not studies.is_current("compatibility", studies.StudyConfig(out_dir=tmp_path, quick=True, seed=1))
    assert not studies.is_current("compatibility", studies.StudyConfig(out_dir=tmp_path, quick=False, seed=0))
    doc = json.loads((tmp_path / "compatibility.json").read_text())
    doc["identity"]["code"] = "0" * 16  # as if written by other code
    (tmp_path / "compatibility.json").write_text(json.dumps(doc))
    assert not studies.is_current("compatibility", cfg)


def test_summary_numbers_become_plain_json():
    doc = _staging._jsonable({"a": np.float32(0.5), "b": np.arange(3), "c": float("nan"),
                               "d": (np.int64(2), True)})
    assert json.dumps(doc, allow_nan=False) == '{"a": 0.5, "b": [0, 1, 2], "c": null, "d": [2, true]}'
    with pytest.raises(UndulateError):
        _staging._jsonable({"x": object()})


def test_the_order_does_not_depend_on_which_study_module_was_imported_first():
    """Ties of ``Study.order`` go by module name, as documented: a process that imported the
    synchronization studies before anything listed them once put them before phase-interaction
    (both order 100), and the order test above failed when it ran after such a test in its process."""
    import subprocess
    import sys

    code = ("import undulate.studies.synchronization, undulate.studies._closed_loop_pairs\n"
            "from undulate import studies\n"
            "print(' '.join(studies.names()))\n")
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True)
    listed = subprocess.run([sys.executable, "-c", "from undulate import studies; print(' '.join(studies.names()))"],
                            capture_output=True, text=True, timeout=300, check=True)
    assert first.stdout == listed.stdout
    names = first.stdout.split()
    assert names.index("phase-interaction") < names.index("synchronization-pairs")
