"""One Warp model and its worlds (:class:`_Group`): the model and data put on the device, the chunk's
buffers, the kernels compiled on threads from a trace of the first step, the step captured as graphs,
launched on the group's own stream and copied back; and what a group reduces on the device
(:class:`_Reduction`)."""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence

import mujoco
import numpy as np

from ..execution import current
from ._warp_device import (_DEVICE_LOCK, CapacityError, capacities, compile_workers, determinism, require,
                           steps_per_graph)
from ._warp_private import private_api
from ._warp_servo import device_inputs
from ._warp_timeline import Timeline

class _Group:
    """One Warp model and its worlds (the scenes ``idx`` of the batch)."""

    # Data fields MuJoCo Warp never recomputes for the static (world-body) geoms and sites: taken per
    # world from each world's own model (the walls of a channel whose width differs per world)
    STATIC_DATA = ("geom_xpos", "geom_xmat", "site_xpos", "site_xmat", "xpos", "xquat", "xmat", "xipos", "ximat")

    def __init__(self, mjm: mujoco.MjModel, idx: np.ndarray, per_world: dict, device: str,
                 models: Sequence[mujoco.MjModel] | None = None, reduce: "_Reduction | None" = None):
        wp, mjw = require()
        self.idx, self.device = idx, device
        self.reduce = None if reduce is None else reduce.on(device, idx)
        nw = len(idx)
        cap = capacities(mjm)
        self.cap = cap
        with wp.ScopedDevice(device):
            batch = {n: nw for n in per_world if not n.startswith("opt.")}
            m = mjw.put_model(mjm, batch_sizes=batch)
            for name, v in per_world.items():
                owner, attr = (m.opt, name[4:]) if name.startswith("opt.") else (m, name)
                cur = getattr(owner, attr)
                inner = tuple(getattr(cur.dtype, "_shape_", ()))
                setattr(owner, attr, wp.array(np.ascontiguousarray(v, dtype=np.float64 if v.dtype.kind == "f" else v.dtype)
                                              .reshape((nw,) + tuple(cur.shape[1:]) + inner), dtype=cur.dtype))
            m.opt.warn_overflow = 0
            m.opt.deterministic = determinism(device)
            m.opt.contact_sensor_maxmatch = cap["contact_sensor_maxmatch"]
            self._mjm, self._models, self._per_world = mjm, models, per_world
            self.d = self._new_data()
            self.m = m
            self.k = wp.zeros(1, dtype=int)
            # the control table's columns: the inputs the model's actuators read (a servo's velocity
            # input, kept in a model derived from the host's, is not one: _warp_servo.device_model)
            self.inputs = device_inputs(mjm)
            self.cols = wp.array(self.inputs.astype(np.int32), dtype=int)
            # its own stream on a GPU: the groups of threads running side by side (studies, gathered
            # sweeps) overlap on the device instead of queueing on its default stream
            # (UNDULATE_WARP_STREAMS=0: every group on the device's current stream, one thread at a time)
            own = wp.get_device(device).is_cuda and current().streams
            self.stream = wp.Stream(device) if own else None
        self.graphs: list = []  # (steps, captured graph), the longest first; none until captured
        self.bufs = None
        self.stepped = False  # its kernels compiled (a first step taken)
        self.nq, self.nv, self.ns, self.nu = mjm.nq, mjm.nv, mjm.nsensordata, len(self.inputs)
        self.timeline = Timeline((mjm.nq, mjm.nv, mjm.nu, mjm.na, mjm.nsensordata, mjm.ngeom,
                                   float(mjm.opt.timestep)), nw, device)

    def _new_data(self):
        """The worlds' Warp data at the first state (the current device): one ``put_data`` of the
        layout scene, with each world's static geoms and sites (the walls) from its own model."""
        wp, mjw = require()
        mjm, models, cap, nw = self._mjm, self._models, self.cap, len(self.idx)
        mjd = mujoco.MjData(mjm)
        mujoco.mj_forward(mjm, mjd)
        try:
            d = mjw.put_data(mjm, mjd, nworld=nw, nconmax=cap["nconmax"], njmax=cap["njmax"])
        except ValueError as e:  # the first state already needs more than was allocated
            raise CapacityError(f"MuJoCo Warp: {e} at the start (allocated per world: {cap})") from None
        if self._per_world and models is not None:
            datas = []
            for mw in models:
                dw = mujoco.MjData(mw)
                mujoco.mj_forward(mw, dw)
                datas.append(dw)
            for name in self.STATIC_DATA:
                arr = getattr(d, name, None)
                if arr is None:
                    continue
                inner = tuple(getattr(arr.dtype, "_shape_", ()))
                v = np.stack([getattr(dw, name) for dw in datas]).reshape((nw,) + tuple(arr.shape[1:]) + inner)
                setattr(d, name, wp.array(v.astype(np.float32), dtype=arr.dtype))
        return d

    def _buffers(self, k: int):
        """The chunk's buffers on the device for at least ``k`` steps -- the control table, then what
        each step leaves (:meth:`_rows`: every step's qpos, qvel and sensors; or, reducing, each
        sample interval's) -- and their host mirrors (pinned on a GPU; with the warm starts, the
        overflow bits and, reducing, the first bad step).  They grow only: a shorter chunk reuses
        them and the captured graph (which names them), so a run's last, shorter chunk needs no new
        capture."""
        wp, _ = require()
        nw = len(self.idx)
        if self.bufs is None or self.bufs[0].shape[0] < k:
            r = self.reduce
            rows = k if r is None else k // r.sps
            with wp.ScopedDevice(self.device):
                out = [wp.zeros((rows, nw, n), dtype=float) for n in (self.nq, self.nv, self.ns)]
                if r is not None:
                    out += [wp.zeros((rows, nw), dtype=float), wp.zeros((rows, nw, len(r.pair_adr)), dtype=float),
                            wp.zeros((rows, nw, len(r.wall_adr)), dtype=float), wp.zeros(nw, dtype=int)]
                self.bufs = (wp.zeros((k, nw, self.nu), dtype=float), *out)
                pinned = self.stream is not None
                self.host = [wp.empty(a.shape, dtype=a.dtype, device="cpu", pinned=pinned)
                             for a in (*self.bufs[1:], self.d.qacc_warmstart, self.d.overflow)]
            self.graphs = []
        return self.bufs

    def _one_step(self):
        wp, mjw = require()
        from . import _warp_kernels as kernels

        table, out = self.bufs[0], self.bufs[1:]
        nw = len(self.idx)
        if table.shape[2]:
            wp.launch(kernels.set_ctrl, dim=(nw, table.shape[2]), inputs=[table, self.k, self.cols, self.d.ctrl])
        mjw.step(self.m, self.d)
        r = self.reduce
        if r is None:
            wp.launch(kernels.record, dim=nw, inputs=[self.d.qpos, self.d.qvel, self.d.sensordata, self.k, *out])
        else:
            wp.launch(kernels.reduce, dim=nw, inputs=[self.d.qpos, self.d.qvel, self.d.sensordata, self.k, r.sps,
                                                      r.pair_dev, r.wall_dev, r.md, r.maxpen_dev, *out])
        wp.launch(kernels.incr, dim=1, inputs=[self.k])

    def launch(self, qpos, qvel, warm, table: np.ndarray, nstep: int) -> None:
        """Start stepping the group's worlds ``nstep`` steps from (qpos, qvel, warm start) under ``table``
        (nstep, nw, nu): on a GPU the steps and the copies of what they leave are queued on the group's
        stream and this returns at once, so that the groups of one batch step side by side
        (:meth:`WarpRollout._step_groups`); :meth:`collect` waits for them."""
        wp, _ = require()
        self._t = (time.time(), time.perf_counter())  # the timeline's: this chunk captures if
        self._capturing = not self.graphs or self.bufs[0].shape[0] < nstep  # first, or its buffers grow
        host = [np.ascontiguousarray(x, dtype=np.float32) for x in (qpos, qvel, warm, table)]
        with wp.ScopedDevice(self.device):
            if self.stream is None:  # Warp's CPU device (no streams): one thread steps at a time
                with _DEVICE_LOCK:
                    self._ready(nstep, host)
                    self._launch(nstep, host)
                    self._copy_out()
            else:
                if self._capturing:
                    with _DEVICE_LOCK, wp.ScopedStream(self.stream):  # allocation, compilation, capture
                        self._ready(nstep, host)
                # Then on this group's own stream, every call naming it: threads stepping other groups
                # (studies side by side, gathered sweeps) overlap with it on the device.  (Warp's current
                # stream is per device, not per thread: it is only changed under the lock above.)
                self._launch(nstep, host)
                self._copy_out()

    def collect(self):
        """Wait for the chunk :meth:`launch` started; returns what its steps left (per step, or reducing
        per sample interval: qpos, qvel, sensors (nw, rows, ...) float64, then the depths, forces and
        first bad steps), the warm starts after, and the overflow bitmask per world."""
        wp, _ = require()
        with wp.ScopedDevice(self.device):
            self._sync()
            out = self._host_rows()
        start, t0 = self._t
        self.timeline.chunk(start, time.perf_counter() - t0, self._nstep, self._capturing)
        return out

    def _upload(self, host) -> None:
        """The chunk's first state (qpos, qvel, warm start) and control table, and the step counter
        (and, reducing, the first bad steps) at 0, copied to the device on the group's stream."""
        wp, _ = require()
        for dst, src in zip((self.d.qpos, self.d.qvel, self.d.qacc_warmstart, self.bufs[0]), host):
            if src.size:
                wp.copy(dst, wp.array(src, dtype=float, device="cpu", copy=False), stream=self.stream)
        wp.copy(self.k, wp.zeros(1, dtype=int, device="cpu"), stream=self.stream)
        if self.reduce is not None:
            wp.copy(self.bufs[-1], wp.zeros(len(self.idx), dtype=int, device="cpu"), stream=self.stream)

    def _ready(self, nstep: int, host) -> None:
        """The chunk's buffers, and on the first call the kernels compiled and the step captured."""
        self._buffers(nstep)
        if not self.graphs:  # the first step compiles the kernels; then captured graphs
            try:
                self._capture(host)
            except (RuntimeError, ValueError) as e:
                if self.m.opt.deterministic and _beyond_determinism(e):
                    raise CapacityError(
                        f"MuJoCo Warp's determinism (UNDULATE_WARP_DETERMINISTIC=1) needs more workspace than Warp "
                        f"can allocate for this model at {len(self.idx)} worlds ({type(e).__name__}: {e}); "
                        "run with UNDULATE_WARP_DETERMINISTIC=0 or with fewer worlds") from None
                raise

    def _capture(self, host) -> None:
        """The first step (kernels compiled, unless already) and the captured graphs."""
        wp, _ = require()
        first = not self.stepped
        if first:  # its kernels compiled, on threads (then captured graphs, on CUDA and on Warp's
            self._upload(host)  # CPU device alike: on the CPU they save Warp's per-launch Python)
            t0 = time.perf_counter()
            _compile_kernels(self)
            self._one_step()
            self._sync()
            first_s = time.perf_counter() - t0
            self.stepped = True
        with wp.ScopedCapture(stream=self.stream) as cap:
            self._one_step()
        self.graphs = [(1, cap.graph)]
        n = steps_per_graph(self.device)
        if n > 1:  # and n steps in one graph: one launch (one Python call on the host) for n steps
            try:
                with wp.ScopedCapture(stream=self.stream) as cap:
                    for _ in range(n):
                        self._one_step()
                self.graphs.insert(0, (n, cap.graph))
            except Exception:  # noqa: BLE001 - the one-step graph steps it all (said in the stats)
                n = 1
        if first:
            _note_first_step(first_s, len(self.idx), self.nv, steps_per_graph=max(n, 1))

    def _launch(self, nstep: int, host) -> None:
        """``nstep`` steps from the chunk's start (again, after a compiling step)."""
        self._upload(host)
        self._nstep = nstep
        self._steps(nstep)

    def _steps(self, nstep: int) -> None:
        """Launch ``nstep`` steps on the group's stream: the longest captured graphs first."""
        wp, _ = require()
        for n, graph in self.graphs:
            for _ in range(nstep // n):
                wp.capture_launch(graph, stream=self.stream)
            nstep %= n

    def _sync(self) -> None:
        """Wait for this group's work on the device (its stream only, on a GPU).

        On a GPU this calls Warp's native stream synchronisation: ``wp.synchronize_stream`` refuses
        while *any* capture is active on the device, and another thread may be capturing its own
        group's step (found on an H100: "Cannot synchronize stream while graph capture is active").
        Captures here are thread-local (``wp.ScopedCapture``'s default mode), under which CUDA
        forbids unsafe calls only in the capturing thread, so waiting for another stream is legal."""
        wp, _ = require()
        if self.stream is None:
            wp.synchronize_device(self.device)
            return
        runtime = private_api().runtime
        if not runtime.core.wp_cuda_stream_synchronize(self.stream.cuda_stream):
            raise RuntimeError(f"MuJoCo Warp: synchronizing a stream on {self.device} failed: "
                               f"{runtime.get_error_string()}")

    def _copy_out(self) -> None:
        """Queue the copies of what the chunk left to the host mirrors (on the group's stream; only
        the chunk's rows), then the warm starts and overflow bits."""
        wp, _ = require()
        srcs = (*self.bufs[1:], self.d.qacc_warmstart, self.d.overflow)
        rows = self._rows()
        for i, (o, a) in enumerate(zip(self.host, srcs)):
            n = rows * int(np.prod(a.shape[1:])) if i < self._per_row() else 0
            if a.size:
                wp.copy(o, a, stream=self.stream, count=n)  # the chunk's rows (0: all)

    def _rows(self) -> int:
        return self._nstep if self.reduce is None else self._nstep // self.reduce.sps

    def _per_row(self) -> int:
        """How many of the host mirrors have the row as first axis."""
        return len(self.bufs) - 1 - (self.reduce is not None)

    def _host_rows(self):
        """The copied chunk, float64, rows first per world (:meth:`collect`), then the warm starts and
        overflow bits (after :meth:`_sync`)."""
        rows, per_row = self._rows(), self._per_row()
        out = []
        for i, o in enumerate(self.host):
            x = o.numpy()
            if i < per_row:
                x = x[:rows]
                x = x.transpose(1, 0, *range(2, x.ndim))
            out.append(x.astype(np.float64) if x.dtype.kind == "f" else x.copy())
        return tuple(out)


class _Reduction:
    """What a group reduces on the device each step (:func:`undulate.simulation._warp_kernels.reduce`):
    steps per sample interval, the pair and wall force sensors' addresses, the min-distance sensor's,
    and each world's penetration bound (m)."""

    def __init__(self, sps: int, pair_adr, wall_adr, md: int, maxpen_m):
        self.sps, self.md = int(sps), int(md)
        self.pair_adr = np.asarray(pair_adr, dtype=np.int32).ravel()
        self.wall_adr = np.asarray(wall_adr, dtype=np.int32).ravel()
        self.maxpen_m = np.asarray(maxpen_m, dtype=np.float32)

    def on(self, device: str, idx: np.ndarray) -> "_Reduction":
        """This reduction for the worlds ``idx`` of a group, with its arrays on ``device``."""
        wp, _ = require()
        r = _Reduction(self.sps, self.pair_adr, self.wall_adr, self.md, self.maxpen_m[idx])
        with wp.ScopedDevice(device):
            r.pair_dev = wp.array(r.pair_adr, dtype=int)
            r.wall_dev = wp.array(r.wall_adr, dtype=int)
            r.maxpen_dev = wp.array(r.maxpen_m, dtype=float)
        return r


def _device_seconds(group: "_Group", nstep: int) -> float:
    """Seconds the device takes for ``nstep`` steps of ``group``'s worlds alone (no transfers; a
    benchmark: benchmarks/bench_gpu_check.py)."""
    wp, _ = require()
    with _DEVICE_LOCK, wp.ScopedDevice(group.device):
        group._buffers(nstep)
        group.k.zero_()
        wp.synchronize()
        t = time.perf_counter()
        if group.graphs:
            group._steps(nstep)
        else:
            for _ in range(nstep):
                group._one_step()
        wp.synchronize()
        return time.perf_counter() - t


def _beyond_determinism(error: Exception) -> bool:
    """Whether ``error`` is Warp refusing a deterministic launch's workspace (its sort-reduce buffers
    exceed what a Warp array may hold: measured on an H200 for a jammed pack, and a pair at 32 768 worlds)."""
    text = str(error)
    return (type(error).__name__ == "WarpDeterminismError" or "atomic-update slots" in text
            or "signed 32-bit integer" in text)


def _traced_modules(group: "_Group") -> list:
    """The Warp modules (with their block sizes) that one step of ``group``'s model launches,
    found by running MuJoCo Warp's step with every launch of this thread only recorded: on
    throwaway data of the same shapes (the step's own copies and fills land there), with the
    constraint solver's iterations unrolled (a conditional loop would wait for kernels that
    never ran).  The kernels are the same ones the real step launches, since MuJoCo Warp
    specialises them on the model and the data's sizes, which are the group's."""
    wp, mjw = require()
    from . import _warp_kernels as kernels

    _normalize_launch_dim = private_api().normalize_launch_dim

    seen: dict = {(k.module, None): None for k in (kernels.set_ctrl, kernels.record, kernels.reduce, kernels.incr)}
    me = threading.get_ident()
    launch, launch_tiled = wp.launch, wp.launch_tiled

    def record(real):
        def stub(kernel, *args, **kw):
            if threading.get_ident() != me:  # another thread's launches go through untouched
                return real(kernel, *args, **kw)
            if _normalize_launch_dim(kw["dim"] if "dim" in kw else args[0])[1] > 0:  # as wp.launch: an
                seen[(kernel.module, kw.get("block_dim"))] = None  # empty launch loads nothing
        return stub

    m = group.m
    conditional = m.opt.graph_conditional
    scratch = group._new_data()
    wp.launch, wp.launch_tiled = record(launch), record(launch_tiled)
    m.opt.graph_conditional = False
    try:
        mjw.step(m, scratch)
    finally:
        wp.launch, wp.launch_tiled = launch, launch_tiled
        m.opt.graph_conditional = conditional
    return list(seen)


def _compile_kernels(group: "_Group") -> None:
    """Compile (or load from Warp's kernel cache) every module ``group``'s first step needs, on
    :func:`compile_workers` threads at once.  Warp compiles a module when a launch first needs
    it, so a first step compiles its modules (41 for a pair) one after another; Warp's native
    compilers run outside its code-generation lock, so modules compiled on threads overlap (on Warp's
    CPU device, 2 cores, a cold kernel cache: a pair's 0.5 s run 39.8 s -> 28.6 s).  Anything the
    trace misses is compiled by the step as before, and a trace that fails leaves everything to the
    step."""
    wp, _ = require()
    n = compile_workers()
    if n <= 1:
        return
    try:
        todo = _traced_modules(group)
    except Exception:  # noqa: BLE001  (an unexpected step path: the first step compiles serially)
        return
    from concurrent.futures import ThreadPoolExecutor

    api = private_api()
    _resolve_launch_block_dim, runtime = api.resolve_launch_block_dim, api.runtime

    device = wp.get_device(group.device)
    todo = [(mod, _resolve_launch_block_dim(device, bd)) for mod, bd in todo]
    saved = runtime.core.wp_cuda_context_get_current() if device.is_cuda else None
    try:  # (a module already loaded and current returns at once; one whose kernels changed recompiles)
        with ThreadPoolExecutor(min(n, len(todo))) as pool:
            for f in [pool.submit(mod.load, device, block_dim=bd) for mod, bd in todo]:
                f.result()
    except Exception as e:  # noqa: BLE001  (what failed here, the first step loads the Warp way, and says why)
        _note_compile_fallback(e)
    finally:  # as wp.force_load does: the caller's CUDA context back
        if saved is not None:
            runtime.core.wp_cuda_context_set_current(saved)


def _note_compile_fallback(error: Exception) -> None:
    """A failed compile on threads: the first step then compiles what is missing one module after
    another, as Warp does; said once per process (a warning), so a slow first step is explained."""
    global _COMPILE_FALLBACK_SAID
    if not _COMPILE_FALLBACK_SAID:
        _COMPILE_FALLBACK_SAID = True
        import warnings

        warnings.warn(f"Warp kernels compiled on threads failed ({type(error).__name__}: {error}); "
                      "the first step compiles them one after another", RuntimeWarning, stacklevel=3)


_COMPILE_FALLBACK_SAID = False


def _note_first_step(seconds: float, nworld: int, nv: int, steps_per_graph: int = 1) -> None:
    """The first step of a Warp model (kernel compilation unless cached, then the graph capture):
    appended as a JSON line to the file ``UNDULATE_WARP_STATS`` names, if set (benchmarks/bench_gpu_check.py
    reports compile time apart from stepping with it)."""
    path = current().stats_file
    if path:
        import json

        with open(path, "a", encoding="utf-8") as f:
            f.write(json.dumps({"first_step_s": seconds, "nworld": nworld, "nv": nv,
                                "steps_per_graph": steps_per_graph}) + "\n")
