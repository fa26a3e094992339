"""The public trajectory schema (:mod:`undulate.schema`): one description of the recorded
variables and scene attributes, used by the simulator, the robot logger and the tracker."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from undulate import Scene, SimOptions, schema
from undulate._source import closure, import_graph
from undulate.observables import middle_link_pose
from undulate.track.calibration import robot_tag_link


def test_importing_the_schema_imports_neither_mujoco_nor_opencv():
    code = ("import sys, undulate.schema as s; s.scene_attrs(__import__('undulate').Scene()); "
            "print(sorted(m for m in ('mujoco', 'cv2') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_robot_and_tracking_reach_the_schema_not_the_simulator():
    graph = import_graph()
    for module in ("undulate.robot.runner", "undulate.track.tracker"):
        reached = closure([module], graph)
        assert "undulate.schema" in reached, module
        assert "undulate.simulation" not in reached, module
    # the compare <-> track circle is broken: comparing needs no tracking code
    assert not {m for m in closure(["undulate.compare"], graph) if m.startswith("undulate.track")}


def test_recordable_names_are_the_schema_in_order():
    assert SimOptions.RECORDABLE == schema.RECORDABLE == tuple(schema.VARIABLES)
    for name, var in schema.VARIABLES.items():
        assert var.dims[0] == "time" and var.units in ("m", "rad", "N"), name


def test_a_simulated_dataset_follows_the_schema():
    from undulate import simulate
    from undulate.simulation import scene_attrs  # still importable from the simulator

    sc = Scene(phases_rad=(0.0, 1.0))
    ds = simulate(sc, SimOptions(duration_s=0.2, sample_rate_hz=20))
    assert set(ds.data_vars) == set(schema.RECORDABLE)
    for name, (dims, units, long_name) in schema.VARIABLES.items():
        assert ds[name].dims == dims and ds[name].attrs == {"units": units, "long_name": long_name}, name
    attrs = schema.scene_attrs(sc)
    assert scene_attrs is schema.scene_attrs
    assert {k: ds.attrs[k] for k in attrs} == attrs
    assert attrs["wavelength"] == pytest.approx(sc.wavelength_m) and attrs["period"] == sc.gait.period_s


def test_a_standing_wave_has_an_infinite_wavelength_attr():
    from undulate import Gait

    sc = Scene(gait=Gait(waves_per_body=0.0))
    assert sc.wavelength_m == math.inf
    assert schema.scene_attrs(sc)["wavelength"] == math.inf


@pytest.mark.parametrize("n_links", [2, 3, 4, 5, 8, 9])
def test_middle_link_pose_is_the_robot_tag_link(n_links):
    # node k of swimmer s at (k, s + k^2): link k runs from (k, s+k^2) to (k+1, s+(k+1)^2)
    import xarray as xr

    k = np.arange(n_links + 1, dtype=float)
    nx = np.broadcast_to(k, (1, 2, n_links + 1))
    ny = np.stack([s + k ** 2 for s in (0.0, 1.0)])[None]
    ds = xr.Dataset({"node_x": (("time", "swimmer", "node"), nx), "node_y": (("time", "swimmer", "node"), ny)})
    x, y, h = middle_link_pose(ds)
    j = robot_tag_link(n_links)
    np.testing.assert_allclose(x, [[j + 0.5, j + 0.5]])
    np.testing.assert_allclose(y, [[(j ** 2 + (j + 1) ** 2) / 2, 1 + (j ** 2 + (j + 1) ** 2) / 2]])
    np.testing.assert_allclose(h, np.arctan2(2 * j + 1, 1.0) * np.ones((1, 2)))
