"""What a run records: sample blocks from states and sensors (:func:`_sample_vars`), the Dataset
(:func:`_to_dataset`), and the recorders that keep them in memory or stream them to netCDF."""

from __future__ import annotations

from typing import TYPE_CHECKING

import functools
import json
import os
import shutil
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from .._signals import deferred
from ..errors import ParameterError
from ..execution import engine_for, memory_available_bytes
from ..params import SimOptions
from ..schema import scene_attrs, variable
from ..scene import CompiledScene, root_link, root_offset_m
from ._backend import backend_attrs, check_backend
from ._mujoco import _state_layout

if TYPE_CHECKING:
    from ._batch import _Batch

RECORDABLE = SimOptions.RECORDABLE
"""Variables a run can record (``SimOptions.record``)."""


def _sample_widths(cs: CompiledScene, record: Sequence[str]) -> dict[str, int]:
    """Values one recorded sample of one scene holds, per variable (time included)."""
    sc = cs.scene
    n, nj, nn = sc.n_swimmers, sc.geometry.n_links - 1, sc.geometry.n_links + 1
    size = {"x": n, "y": n, "heading": n, "node_x": n * nn, "node_y": n * nn, "joint_angle": n * nj,
            "joint_command": n * nj, "joint_error": n * nj, "contact_force_pair": max(0, n - 1),
            "contact_force_wall": len(cs.index.wall_names), "penetration": 1, "gait_phase": n}
    return {"time": 1, **{v: size[v] for v in record}}


def _per_sample_bytes(cs: CompiledScene, record: Sequence[str]) -> int:
    """Bytes one recorded sample of one scene takes (float64), time included."""
    return 8 * sum(_sample_widths(cs, record).values())


def _file_bytes(cs: CompiledScene, record: Sequence[str], n_samples: int) -> int:
    """An upper bound on the netCDF file :class:`_NetCDFRecorder` writes for ``n_samples`` samples: each
    variable in whole HDF5 chunks, plus the header, coordinates and attributes."""
    total = _NetCDFRecorder.HEADER_BYTES
    for width in _sample_widths(cs, record).values():
        if width == 0:
            continue
        chunk = _chunk_samples((width,), n_samples)
        total += -(-n_samples // chunk) * chunk * 8 * width
    return total


def _chunk_samples(sample_shape, max_samples: int) -> int:
    """Samples per HDF5 chunk of a streamed variable whose samples have ``sample_shape`` (float64):
    about :attr:`_NetCDFRecorder.CHUNK_BYTES`, and no more than the run's ``max_samples``."""
    per_sample = 8 * max(1, int(np.prod(sample_shape)))
    return max(1, min(_NetCDFRecorder.CHUNK_BYTES // per_sample, int(max_samples)))


def _check_fits(compiled: Sequence[CompiledScene], record: Sequence[str], n_samples: int,
                outs: Sequence[Path] | None) -> None:
    """Refuse, before stepping, a recording that cannot fit in memory or on disk."""
    need = sum(_per_sample_bytes(c, record) for c in compiled) * (n_samples + 1)
    gib = 2.0**30
    if outs is None:
        have = memory_available_bytes()
        if 2 * need > have:  # the samples plus the Dataset built from them
            raise ParameterError(
                "duration_s / sample_rate_hz (--duration / --sample-rate)",
                f"small enough for the recording to fit in memory: it needs {2 * need / gib:.3g} GiB, "
                f"{have / gib:.3g} GiB is available (stream it to a file with out=, or record fewer "
                f"variables with SimOptions.record)", None)
    else:
        need = sum(_file_bytes(c, record, n_samples + 1) for c in compiled) + _NetCDFRecorder.SPACE_MARGIN_BYTES
        for path in outs:
            free = shutil.disk_usage(Path(path).resolve().parent).free
            if need > free:
                raise ParameterError(
                    "duration_s / sample_rate_hz (--duration / --sample-rate)",
                    f"small enough for the recording to fit on disk: it needs {need / gib:.3g} GiB, "
                    f"{free / gib:.3g} GiB is free at {Path(path).resolve().parent}", None)


def _check_chunk_fits(compiled: Sequence[CompiledScene], chunk_steps: int, timestep_s: float,
                      reduced: bool, automatic: bool = False) -> None:
    """Refuse, before stepping, a chunk whose every-step buffers cannot fit in memory.  A chunk spans
    at least one sample interval (each sample's forces are means over its interval's steps, and a
    closed-loop chunk whole control periods), so a long interval of short steps -- a low sample rate
    against a tiny time step -- would hold all its steps at once.  ``reduced``: the device keeps the
    states and sensors (:func:`undulate.simulation._reduced_on_device`), the host only the controls;
    ``automatic``: the time step is the scene's own (:func:`undulate.scene.auto_timestep`)."""
    m = compiled[0].model
    per_step = m.nu + (0 if reduced else _state_layout(m)[1] + m.nsensordata)  # what _Stepper._buffers holds
    need = 2 * 8 * len(compiled) * chunk_steps * per_step  # the float64 buffers and the arrays made from them
    have = memory_available_bytes()
    if need > have:
        gib = 2.0**30
        step = f"{timestep_s:.3g} s" + (" (the automatic time step for this scene)" if automatic else "")
        raise ParameterError(
            "sample_rate_hz / timestep_s (--sample-rate / --timestep)",
            f"few enough steps in a sample interval for one interval's steps to fit in memory: {chunk_steps:.3g} "
            f"steps of {step} need {need / gib:.3g} GiB, {have / gib:.3g} GiB is available (record more often, "
            "or take a longer time step)", None)


class _MemoryRecorder:
    """Collects each chunk's samples; the Dataset is built once at the end."""

    def __init__(self):
        self.blocks: list[dict] = []

    def add(self, block: dict) -> None:
        self.blocks.append(block)

    def finish(self, build) -> xr.Dataset:
        merged = {k: np.concatenate([b[k] for b in self.blocks]) for k in self.blocks[0]}
        self.blocks = []
        return build(merged)


class _NetCDFRecorder:
    """Writes the samples through to a netCDF file (unlimited ``time``).

    Chunks' samples are held until about :attr:`FLUSH_BYTES` have gathered and
    then appended in one write (each h5netcdf append costs ~1 ms per variable:
    appending every rollout chunk took a third of a long pair run), so memory
    stays bounded by that much plus one chunk.  The file is written to a
    temporary path beside ``path`` (:func:`undulate._io.temporary_path`) and
    fsync-ed and renamed into place by :meth:`finish`; :meth:`abort` removes it.
    """

    FLUSH_BYTES = 1 << 20
    CHUNK_BYTES = 1 << 20
    """HDF5 chunks along time hold about this much of a variable, or the whole run where it is shorter."""
    HEADER_BYTES = 1 << 18
    """What a file holds besides its samples, at most (measured: ~70 kB for a pair and for six swimmers:
    attributes, the per-swimmer coordinates and HDF5's own structures)."""

    def __init__(self, path: Path, max_samples: int):
        from .. import _io

        self.path = Path(path)
        self.max_samples = int(max_samples)
        self.tmp = _io.temporary_path(self.path)
        self.file = None
        self.pending: list[dict] = []
        self.pending_bytes = 0

    def add(self, block: dict, build) -> None:
        from .._io import hdf5_writes, netcdf_bytes, write_bytes

        if self.file is None:  # the first block defines the file: variables, attrs, coordinates
            import h5netcdf

            ds = build(block)
            # HDF5 chunks of ~1 MiB along time: chunking by the first block's shape would make one
            # chunk per few samples, and HDF5's chunk index (held in memory) would grow with the run.
            # No longer than the run: a chunk is stored whole, so a 30 s pair run's 1 MiB chunks made
            # a 13.7 MB file of 0.2 MB of samples
            enc = {name: {"chunksizes": (_chunk_samples(v.shape[1:], self.max_samples),
                                         *(max(1, n) for n in v.shape[1:]))}  # HDF5: no empty chunk sides
                   for name, v in ds.variables.items() if v.dims[:1] == ("time",)}
            # the file's skeleton (no samples) built in memory and written as bytes: a full disk fails the
            # plain write cleanly (HDF5's own failure paths corrupt its memory: _io.netcdf_bytes); the
            # samples are appended as every later block's are
            skeleton = netcdf_bytes(ds.isel(time=slice(0, 0)), compress=False, unlimited_dims=["time"], encoding=enc)
            write_bytes(self.tmp, skeleton, self.path)
            with hdf5_writes(self.tmp, self.path), deferred():  # a SIGTERM waits: a half-built File fails at exit
                self.file = h5netcdf.File(self.tmp, "a")  # kept open: reopening per chunk leaks memory
            self.appended = [n for n, v in self.file.variables.items() if v.dimensions[:1] == ("time",)]
            self.pending.append(block)
            self.pending_bytes = sum(np.asarray(block[n]).nbytes for n in self.appended)
            self._flush()
            return
        self.pending.append(block)
        self.pending_bytes += sum(np.asarray(block[n]).nbytes for n in self.appended)
        if self.pending_bytes >= self.FLUSH_BYTES:
            self._flush()

    def _flush(self) -> None:
        if not self.pending:
            return
        from .._io import hdf5_writes

        f = self.file
        n0 = f.dimensions["time"].size
        k = sum(len(b["time"]) for b in self.pending)
        self._check_space(self.pending_bytes)
        with hdf5_writes(self.tmp, self.path):  # a failed write: WriteError, the file given up and removed
            f.resize_dimension("time", n0 + k)
            # each variable through its own h5py handle, flushed before the handle goes: h5netcdf looks
            # one up per write and releases it after, and HDF5 writes a dataset's chunks when its last
            # handle goes, where a failure (a full disk) is only printed, and the run went on into
            # HDF5's corrupt memory (a crash at exit).  The flush writes them, and raises.  (All held
            # at once, or for the whole run, their chunk caches took 15-85 MB more.)
            for name in self.appended:
                h = f.variables[name]._h5ds
                h[n0:n0 + k, ...] = np.concatenate([np.asarray(b[name]) for b in self.pending])
                h.flush()
                del h
        self.pending, self.pending_bytes = [], 0

    SPACE_MARGIN_BYTES = 4 << 20
    """Free space kept on the disk: a run stops (:class:`~undulate.errors.WriteError`) before an append
    would leave less, so HDF5 itself never meets a full disk (its failure paths corrupt its memory) and
    the file still closes."""

    def _check_space(self, nbytes: int) -> None:
        import errno

        from ..errors import WriteError

        try:
            free = shutil.disk_usage(self.tmp.parent).free
        except OSError:
            return
        if free < nbytes + self.SPACE_MARGIN_BYTES:
            raise WriteError(self.path, OSError(errno.ENOSPC, f"{os.strerror(errno.ENOSPC)}: the disk filled "
                                                               "during the run"))

    def _close(self) -> None:
        from .._io import hdf5_writes

        if self.file is not None:
            f, self.file = self.file, None
            with hdf5_writes(self.tmp, self.path), deferred():  # not left half closed by a SIGTERM
                f._h5file.flush()  # a failure raises here, not in the close's finalizers
                f.close()

    def finish(self) -> xr.Dataset:
        if self.file is not None:
            self._flush()
        self._close()
        from .. import _io

        _io.commit(self.tmp, self.path)
        with deferred():
            return xr.open_dataset(self.path, engine="h5netcdf")

    def abort(self) -> None:
        """Remove the file; never raises (a run's own error is what the caller reports)."""
        from .. import _io

        self.pending = []
        try:
            self._close()
        except Exception:  # noqa: BLE001 - a file that cannot be closed is given up; the run's own error is reported
            _io._give_up_hdf5(self.tmp)
        _io.discard(self.tmp)


def _outs(out, nb: int) -> list[Path] | None:
    if out is None:
        return None
    paths = [Path(out)] if isinstance(out, (str, os.PathLike)) else [Path(p) for p in out]
    if len(paths) != nb:
        raise ParameterError("out", f"{nb} path(s), one per scene", out)
    for p_ in paths:
        if p_.suffix.lower() != ".nc":
            raise ParameterError("out", "a path ending in .nc (netCDF)", str(p_))
        if not p_.resolve().parent.is_dir():
            raise ParameterError("out", "a path in an existing directory", str(p_))
    return paths


class _Recorders:
    """One recorder per scene of a batch (in memory, or streamed to its ``out`` file) and the stopping
    rule that sees every block recorded (one for the batch, or one per scene)."""

    def __init__(self, bt: _Batch, stop):
        self.bt, self.stop = bt, stop
        self.per_scene = stop is not None and not callable(stop)
        if self.per_scene:
            self.stop = list(stop)
            if len(self.stop) != bt.nb or not all(callable(r) for r in self.stop):
                raise ParameterError("stop", f"a stopping rule, or one per scene ({bt.nb} callables)", stop)
        self.reasons: list[str | None] = [None] * bt.nb
        self.recorders = [_MemoryRecorder() for _ in range(bt.nb)] if bt.outs is None else \
            [_NetCDFRecorder(p_, bt.n_samples + 1) for p_ in bt.outs]
        asked = check_backend(bt.requested)  # the engine asked for (the session's where left out)
        self.builders = [functools.partial(_to_dataset, cs, bt.options, record=bt.options.recorded,
                                           timestep_auto=bt.requested.timestep_s is None,
                                           control_rate_hz=None if bt.ctl is None else 1.0 / (bt.tick * bt.dt),
                                           controller_kind=None if bt.ctl is None else bt.ctl.kind,
                                           engine=_engine_attrs(asked, bt.options, cs.scene.n_swimmers, bt.nb))
                         for cs in bt.compiled]

    def rule(self, b: int) -> str:
        """The stopping rule of scene ``b``, as text ("" without one)."""
        r = self.stop[b] if self.per_scene else self.stop
        return "" if r is None else str(getattr(r, "rule", repr(r)))

    def record(self, blocks: list[dict | None]) -> bool:
        """Record one block per scene still stepped (None: a scene that has stopped); whether every
        scene has now stopped (its reason in :attr:`reasons`)."""
        for b, block in enumerate(blocks):
            if block is not None:
                self.recorders[b].add(block) if self.bt.outs is None else self.recorders[b].add(block, self.builders[b])
        if self.stop is None:
            return False
        if not self.per_scene:
            reason = self.stop(blocks)
            self.reasons = [reason] * len(blocks)
            return bool(reason)
        for b, block in enumerate(blocks):
            if block is not None and self.reasons[b] is None:
                self.reasons[b] = self.stop[b]([block]) or None
        return all(r is not None for r in self.reasons)

    def finish(self) -> list[xr.Dataset]:
        """One Dataset per scene (built in memory, or opened from its file)."""
        return [r.finish(self.builders[b]) if self.bt.outs is None else r.finish()
                for b, r in enumerate(self.recorders)]

    def abort(self) -> None:
        """After a failure: remove the files being streamed (nothing to do in memory)."""
        if self.bt.outs is not None:
            for r in self.recorders:
                r.abort()


def _link_angles(yaw: np.ndarray, joints: np.ndarray, root: int) -> np.ndarray:
    """World orientation of each link's body axis (head->tail), rad.

    ``yaw``: (..., ) orientation of the root link ``root``; ``joints``:
    (..., N-1) -> (..., N).
    """
    c = np.concatenate([np.zeros_like(joints[..., :1]), np.cumsum(joints, axis=-1)], axis=-1)
    return yaw[..., None] + c - c[..., root:root + 1]


def _sample_vars(cs: CompiledScene, t, qpos, sens, fpair, fwall, pen, record, cmd=None, phase=None) -> dict:
    """The recorded variables of a block of samples (leading axis: time) as arrays.

    ``cmd``, ``phase``: the commanded joint angles and gait phases at the samples
    (closed-loop controllers); None: the open-loop gait's."""
    sc, ix = cs.scene, cs.index
    g = sc.geometry
    out = {"time": t}
    rl = root_link(g.n_links)
    xs0, ys0 = sc.initial_x_m() - g.length_m / 2 + root_offset_m(sc), sc.initial_y_m()
    root = qpos[:, ix.qpos_root]  # (T, n, 3): the body's midpoint and root-link orientation, plus the offset
    if sc.hold_x:  # no x joint (Scene.hold_x): the midpoint stays at its initial x
        root = root.copy()
        root[..., 0] = 0.0
    alpha = qpos[:, ix.qpos_joint]  # (T, n, nj)
    theta = _link_angles(root[..., 2], alpha, rl)  # (T, n, N)
    l = g.link_length_m
    # the head tip: back from the root frame (the body's midpoint) along the root link and the head-side links
    cx, cy = np.cos(theta), np.sin(theta)
    a = root_offset_m(sc) - rl * l  # the root frame's distance behind the root link's head end
    rx = root[..., 0] + xs0 - a * cx[..., rl] - l * cx[..., :rl].sum(axis=-1)
    ry = root[..., 1] + ys0 - a * cy[..., rl] - l * cy[..., :rl].sum(axis=-1)
    if "x" in record or "y" in record:
        # centre of mass of equal links = mean of the link midpoints, at the recorded state itself (the
        # subtree-COM sensor would read the state one step earlier)
        hx = rx[..., None] + l * (np.cumsum(cx, axis=-1) - cx / 2)
        hy = ry[..., None] + l * (np.cumsum(cy, axis=-1) - cy / 2)
        out["x"], out["y"] = hx.mean(axis=-1), hy.mean(axis=-1)
    if "heading" in record:
        out["heading"] = theta.mean(axis=-1)
    if "node_x" in record:
        out["node_x"] = np.concatenate([rx[..., None], rx[..., None] + l * np.cumsum(cx, axis=-1)], axis=-1)
    if "node_y" in record:
        out["node_y"] = np.concatenate([ry[..., None], ry[..., None] + l * np.cumsum(cy, axis=-1)], axis=-1)
    if cmd is None:
        cmd = sc.gait.joint_angles(t, sc.phases_rad, g.n_links)
    if phase is None:  # the open-loop gait: psi = 2 pi f t - phi (undulate.control)
        phase = (2 * np.pi * sc.gait.frequency_hz) * np.asarray(t, dtype=float)[:, None] - np.asarray(sc.phases_rad)[None]
    out["joint_angle"], out["joint_command"], out["joint_error"] = alpha, cmd, np.abs(alpha - cmd)
    out["gait_phase"] = phase
    out["contact_force_pair"], out["contact_force_wall"], out["penetration"] = fpair, fwall, pen
    return {k: v for k, v in out.items() if k == "time" or k in record}


def _engine_attrs(asked: SimOptions, options: SimOptions, n_swimmers: int, n_scenes: int) -> dict[str, str]:
    """Which engine stepped a run (``engine``: ``options``'s) and which was asked for (``engine_requested``:
    ``asked``'s, resolved); where they differ, why (``engine_reason``: a lone swimmer or a small batch asked
    of Warp on the cores, :func:`undulate.execution.engine_for`)."""
    attrs = {"engine": options.backend, "engine_requested": asked.backend}
    if options.backend != asked.backend:
        _, why = engine_for(asked.backend, asked.device, n_swimmers=n_swimmers)
        if why is None:
            _, why = engine_for(asked.backend, asked.device, n_scenes=n_scenes)
        attrs["engine_reason"] = f"{why or 'the execution policy'}: undulate.execution.engine_for"
    return attrs


def _to_dataset(cs: CompiledScene, options: SimOptions, block: dict, *, record=RECORDABLE,
                timestep_auto: bool = False, control_rate_hz: float | None = None,
                controller_kind: str | None = None, engine: dict[str, str] | None = None) -> xr.Dataset:
    from ..provenance import provenance

    sc, ix = cs.scene, cs.index
    g = sc.geometry
    n, nj = sc.n_swimmers, g.n_links - 1
    sps = options.steps_per_sample

    config = {"scene": sc.to_dict(), "options": options.to_dict(), "timestep_auto": timestep_auto}
    ds = xr.Dataset(
        {name: variable(name, block[name]) for name in RECORDABLE if name in record},
        coords={
            "time": ("time", block["time"], {"units": "s", "long_name": "time"}),
            "swimmer": ("swimmer", np.arange(n)),
            "joint": ("joint", np.arange(nj)),
            "node": ("node", np.arange(g.n_links + 1)),
            "pair": ("pair", np.arange(max(0, n - 1))),
            "wall": ("wall", list(ix.wall_names)),
            "phase": ("swimmer", np.asarray(sc.phases_rad), {"units": "rad", "long_name": "gait phase phi"}),
        },
        attrs={
            "title": "undulate simulation",
            **scene_attrs(sc),
            "timestep": options.timestep_s,
            "timestep_units": "s",
            "timestep_source": "auto (undulate.scene.auto_timestep)" if timestep_auto else "explicit",
            "sample_interval": sps * options.timestep_s,
            "controller": controller_kind or cs.scene.controller.kind,
            "control_rate": control_rate_hz if control_rate_hz is not None else 0.0,
            "control_rate_units": "Hz (0: open loop, set-points at every step)",
            "conventions": "heads toward -x; body wave travels +x; dx = x_upper - x_lower, "
                           "dphi = phi_upper - phi_lower; compatibility dx = lambda dphi / 2pi",
            "config": json.dumps(config),
            **backend_attrs(options),
            **(engine or {"engine": options.backend, "engine_requested": options.backend}),
            **{f"provenance_{k}": v for k, v in provenance().items()},
        },
    )
    return ds
