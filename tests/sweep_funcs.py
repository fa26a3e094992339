"""Cheap but real sweep functions for tests/test_sweep.py.

They live in their own module (not in the test file) so that spawned pool
processes and Dask workers can import them: the test adds this folder to
``sys.path`` and the workers inherit it (multiprocessing's "spawn" passes the
parent's ``sys.path`` on).
"""

from __future__ import annotations

import os
import signal

import mujoco
import numpy as np
import xarray as xr
from mujoco import rollout

from undulate.errors import DivergenceError
from undulate.sweep import batched_sweep_function

_PENDULUM = """
<mujoco model="damped pendulum">
  <option timestep="{dt}" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="bob">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="{damping}"/>
      <geom type="capsule" fromto="0 0 0 0 0 -{length}" size="0.02" mass="1"/>
    </body>
  </worldbody>
</mujoco>
"""


def pendulum(point: dict, seed: int) -> xr.Dataset:
    """A damped pendulum released from a random angle (drawn from ``seed``).

    ``point``: ``damping_Nms`` (joint damping, N m s/rad; a negative value
    pumps energy in: the swing grows and the run raises
    :class:`DivergenceError`), ``length_m``, and
    optionally ``duration_s`` (default 2 s).  Returns the angle sampled at
    50 Hz and its final value.
    """
    dt = 0.002
    model = mujoco.MjModel.from_xml_string(
        _PENDULUM.format(dt=dt, damping=point["damping_Nms"], length=point["length_m"])
    )
    data = mujoco.MjData(model)
    data.qpos[0] = np.random.default_rng(seed).uniform(-1.0, 1.0)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state0, spec)
    nstep = int(round(point.get("duration_s", 2.0) / dt))
    state, _ = rollout.rollout(model, data, state0[None], nstep=nstep)
    angle = state[0, :, 1]  # FULLPHYSICS state: time, qpos, qvel, ...
    half = nstep // 2
    if not np.all(np.isfinite(angle)) or np.abs(angle[half:]).max() > 1.001 * np.abs(angle[:half]).max():
        raise DivergenceError(f"pendulum swing grows (damping {point['damping_Nms']} N m s/rad)")
    every = 10
    t = (np.arange(nstep) + 1)[::every] * dt
    return xr.Dataset(
        {
            "angle": ("time", angle[::every], {"units": "rad"}),
            "final_angle": ((), angle[-1], {"units": "rad"}),
        },
        coords={"time": ("time", t, {"units": "s"})},
        attrs={"model": "damped pendulum"},
    )


def pendulum_batch(points: list[dict], seeds: list[int]) -> list[xr.Dataset]:
    """The batched form of :func:`pendulum` (``run_sweep(..., batched=True)``)."""
    return [pendulum(p, s) for p, s in zip(points, seeds)]


@batched_sweep_function
def pendulum_batch_marked(points: list[dict], seeds: list[int], *, scale: float = 1.0) -> list[xr.Dataset]:
    """:func:`pendulum_batch`, marked as a batched sweep function (``run_sweep`` needs no ``batched=True``);
    ``scale`` multiplies the damping (a keyword a ``functools.partial`` can bind)."""
    return [pendulum({**p, "damping_Nms": p["damping_Nms"] * scale}, s) for p, s in zip(points, seeds)]


def swimmer_pair(point: dict, seed: int) -> xr.Dataset:
    """A pair of real swimmers (``undulate.simulate``), phase lag ``dphi_rad``.

    ``point``: ``dphi_rad`` and optionally ``duration_s`` (default 2 s).
    Returns the centres ``x``, ``y`` (time, swimmer) in metres; ``seed`` is
    unused (the simulation is deterministic).
    """
    from undulate.params import Scene, SimOptions
    from undulate.simulation import simulate

    ds = simulate(Scene(phases_rad=(0.0, point["dphi_rad"])), SimOptions(duration_s=point.get("duration_s", 2.0)))
    return ds[["x", "y"]]


def pendulum_or_crash(point: dict, seed: int) -> xr.Dataset:
    """:func:`pendulum`, except that a negative damping kills the worker process
    outright (SIGKILL), as a crash in C code or the out-of-memory killer would."""
    if point["damping_Nms"] < 0:
        os.kill(os.getpid(), signal.SIGKILL)
    return pendulum(point, seed)


def worker_pid(point: dict, seed: int) -> xr.Dataset:
    """The id of the process that ran the point (tests of the warm worker pool)."""
    return xr.Dataset({"pid": ((), np.int64(os.getpid()))})


def result_data(ds: xr.Dataset) -> xr.Dataset:
    """A sweep's dataset without its provenance attrs (timing and host differ between runs)."""
    ds = ds.copy()
    ds.attrs = {k: v for k, v in ds.attrs.items() if not k.startswith("provenance_")}
    return ds


def mixed(point: dict, seed: int) -> xr.Dataset:
    """A Dataset of every kind a merge meets, cheap (tests of reading run files raw): float series
    with NaN, int64 (stored as int32), a per-run non-index coordinate, attributes some runs share and
    some do not; with ``point["kind"]`` 1 also a boolean and a string (whose decoding xarray owns), 2
    a float with a non-NaN fill value (masked by xarray where a value equals it), 3 the layout of 0
    with another attribute value on a variable in run 2 (a file that does not fit the first run's
    layout), 4 an int64 beyond int32 (the run file is netCDF-4)."""
    rng = np.random.default_rng(seed)
    k = int(point.get("kind", 0))
    t = np.arange(5) * 0.1
    v = rng.normal(size=(5, 2))
    v[int(point["i"]) % 5, 0] = np.nan
    ds = xr.Dataset(
        {"v": (("time", "swimmer"), v, {"units": "m", "long_name": "value"}),
         "big": ((), np.int64((2**40 if k == 4 else 2**20) + int(point["i"])), {"units": "1"}),
         "count": (("swimmer",), np.array([1, int(point["i"])], dtype=np.int32), {"units": "1"})},
        coords={"time": ("time", t, {"units": "s"}), "tag": ((), float(point["i"]) * 0.5, {"units": "m"})},
        attrs={"shared": "same", "arr": np.array([1.0, 2.0]), "own": f"run {point['i']}", "nan": np.nan},
    )
    if k == 1:
        ds["flag"] = ((), bool(int(point["i"]) % 2), {"units": "1"})
        ds["name"] = ((), np.array(f"n{point['i']}"))
    if k == 2:
        ds["v"].encoding["_FillValue"] = -1.0
        ds["v"][0, 1] = -1.0 if int(point["i"]) % 2 else 0.5
    if k == 3 and int(point["i"]) == 2:
        ds["v"].attrs["long_name"] = "another value"
    return ds


def pendulum_disk_full(point: dict, seed: int) -> xr.Dataset:
    """:func:`pendulum`, except that while the file named by ``point["full_flag"]`` exists, a point with
    ``damping_Nms`` >= 1 meets a full disk (a :class:`~undulate.errors.WriteError`, as
    ``simulate(out=...)`` raises there)."""
    import errno

    from undulate.errors import WriteError

    if point["damping_Nms"] >= 1 and os.path.exists(point["full_flag"]):
        raise WriteError(os.path.join(os.path.dirname(point["full_flag"]), "run.nc"),
                         OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)))
    return pendulum({k: v for k, v in point.items() if k != "full_flag"}, seed)


def execution_seen(point: dict, seed: int) -> xr.Dataset:
    """The execution settings in effect where the run ran (tests/test_execution.py): the largest batch
    asked of Warp that steps on the cores (``cores_up_to``, -1 for "by the device") and the process."""
    from undulate.execution import current

    ex = current()
    return xr.Dataset({"cores_up_to": ((), -1 if ex.cores_up_to is None else ex.cores_up_to),
                       "pid": ((), os.getpid())})
