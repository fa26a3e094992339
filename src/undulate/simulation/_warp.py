"""The MuJoCo Warp backend: every scene of a batch is one world of a Warp model.

:class:`WarpRollout` has the interface of :class:`undulate.simulation._WarmRollout` (step every
scene ``nstep`` steps from the given FULLPHYSICS states under the given controls, into per-step
state and sensor arrays), so the recorder, the stopping rules, the divergence checks and the
checkpoints of :mod:`undulate.simulation` are shared by both backends.  Each call uploads the
states and the chunk's control table, steps the worlds on the device (one captured graph per step,
on a GPU and on Warp's CPU device, each Warp model on its own stream on a GPU) and downloads the
chunk once.  Open-loop chunks are reduced on the device (:meth:`WarpRollout.rollout_samples`: each
sample interval's last state and sensors, deepest penetration, mean contact forces and the first
bad step), closed-loop ones record every step (their controllers sense at the control rate).

What differs from the MuJoCo (CPU) backend, and why the results still agree
(tests/test_warp.py, docs/gpu.md):

* **Servos.**  MuJoCo Warp 4.0 has no ``pid`` actuator.  The Warp model expresses each servo as
  an affine position servo (:data:`undulate.scene.SERVO_MODELS`), and the set-point slew limit
  that MuJoCo's ``pid`` applies inside the step (``Servo.max_speed_rad_s``) is applied here to the
  set-point stream, step by step, with the same rule: the slew state moves toward the command by
  at most ``slewmax dt`` per step.  On the CPU the two expressions agree to 1e-16 m over 3000
  steps; the slew state is carried in the FULLPHYSICS ``act`` slots as MuJoCo's is.
  Servos with an integral term (``ki > 0``) are refused.
* **DIAGEXACT** (exact constraint regularisation) is not in MuJoCo Warp 4.0: the Warp model steps
  without it.
* **Precision**: float32 on the device; the clock is kept in float64 on the host.
* **Capacities**: contacts and constraint rows per world, and the contact sensors' match
  buffer, are sized from the scene (:func:`capacities`); an overflow raises
  :class:`~undulate.errors.CapacityError` naming the capacity instead of a per-step print.
* **Per-world parameters**: scenes of one structure that differ in a parameter MuJoCo Warp can
  batch (channel width, drag, gains, contact stiffness, ...) share one Warp model with that field
  given per world; scenes that differ in anything else are stepped as separate Warp models.
"""

from __future__ import annotations

import functools
import itertools
import json
import os
import sys
import threading
import time
from collections.abc import Sequence

import mujoco
import numpy as np

from ..errors import ParameterError, UndulateError
from ._env import BATCH_LABEL, env_count, env_switch, is_cpu_device, usable_cpus

__all__ = ["WarpRollout", "available", "require", "capacities", "CapacityError", "DEVICES", "PRECISION"]

DEVICES = ("cpu", "cuda")
"""Devices the Warp backend steps on (``SimOptions.device``; None: ``cuda`` if present, else ``cpu``)."""
PRECISION = "float32"
"""The Warp backend's floating-point precision (recorded in provenance)."""

EXTRA_HINT = "pip install 'undulate[gpu]' (mujoco-warp and warp-lang)"


class CapacityError(UndulateError):
    """A Warp world needed more contacts, constraint rows or sensor matches than were allocated."""


_LOCK = threading.Lock()
_DEVICE_LOCK = threading.RLock()


@functools.lru_cache(maxsize=1)
def _modules():
    import warp as wp

    wp.config.quiet = True  # before mujoco_warp's import initialises Warp: no banner, no per-module lines
    if hasattr(wp, "LOG_WARNING"):
        wp.config.log_level = wp.LOG_WARNING
    import mujoco_warp as mjw

    return wp, mjw


def available() -> bool:
    """Whether the ``gpu`` extra (mujoco-warp, warp-lang) is importable."""
    try:
        _modules()
    except ImportError:
        return False
    return True


def require():
    """``(warp, mujoco_warp)``, or a ParameterError naming the extra to install."""
    try:
        return _modules()
    except ImportError:
        raise ParameterError("backend", f"'mujoco', or 'warp' once the gpu extra is installed: {EXTRA_HINT}",
                             "warp") from None


@functools.lru_cache(maxsize=1)
def versions() -> str:
    """``"mujoco-warp X, warp-lang Y"`` (provenance; read once a process, as
    :func:`undulate.provenance.provenance`'s versions are: every run's Dataset records it, and
    reading a distribution's metadata costs ~1.5 ms, a tenth of a gathered run's host time)."""
    from ..provenance import package_version

    return f"mujoco-warp {package_version('mujoco-warp', '?')}, warp-lang {package_version('warp-lang', '?')}"


_NO_DRIVER = b"Warp CUDA warning: Could not find or load the NVIDIA CUDA driver."


@functools.lru_cache(maxsize=1)  # once a process (wp.init() does nothing after its first call)
def _init(wp) -> None:
    """``wp.init()`` without the line Warp's C library writes on stderr on a machine with no CUDA driver
    (every Warp run on the CPU device would print it; a ``cuda`` request there is refused by
    :func:`resolve_device` naming the device instead).  Everything else it writes is passed on."""
    import tempfile

    sys.stderr.flush()
    with tempfile.TemporaryFile() as caught:
        saved = os.dup(2)
        try:
            os.dup2(caught.fileno(), 2)
            try:
                wp.init()
            finally:
                os.dup2(saved, 2)
        finally:
            os.close(saved)
        caught.seek(0)
        kept = b"".join(line for line in caught.read().splitlines(keepends=True) if not line.startswith(_NO_DRIVER))
    if kept:
        os.write(2, kept)


def resolve_device(device: str | None) -> str:
    """``device`` checked against what this machine has (None: ``cuda`` if present, else ``cpu``)."""
    wp, _ = require()
    with _LOCK:
        _init(wp)
    if device is None:
        return "cuda" if wp.is_cuda_available() else "cpu"
    if device not in DEVICES:
        raise ParameterError("device", "'cpu' or 'cuda'", device)
    if device == "cuda" and not wp.is_cuda_available():
        raise ParameterError("device", "'cpu' on this machine (no CUDA device is visible to Warp)", device)
    return device


def device_name(device: str) -> str:
    """The device's own name (e.g. 'NVIDIA H100 80GB HBM3', or the CPU's)."""
    wp, _ = require()
    return str(wp.get_device(device).name)


def capacities(mjm: mujoco.MjModel) -> dict[str, int]:
    """Per-world capacities for a scene: contacts (``nconmax``), constraint rows (``njmax``) and
    the contact sensors' match buffer (``contact_sensor_maxmatch``).

    Every colliding geom of a swimmer can touch its two lateral neighbours' geoms along its
    length and a wall; capsule pairs and capsule-plane pairs make at most 2 contacts each.
    The bound used is 6 contacts per colliding geom plus 16.  Constraint rows: per contact, 1
    for a frictionless contact (condim 1), else ``2 (condim - 1)`` in a pyramidal friction cone
    or ``condim`` in an elliptic one; plus one per joint limit, per dof with friction loss and
    per equality row (6 at most each), and 16.  (A frictionless contact counted as 0 rows would let a
    group of three overflow.)"""
    colliding = int(((mjm.geom_contype != 0) | (mjm.geom_conaffinity != 0)).sum())
    nconmax = 6 * colliding + 16
    condim = max([int(mjm.geom_condim.max()) if mjm.ngeom else 3] + ([int(mjm.pair_dim.max())] if mjm.npair else []))
    pyramidal = mjm.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    rows = 1 if condim == 1 else 2 * (condim - 1) if pyramidal else condim
    other = int(mjm.njnt) + int((mjm.dof_frictionloss > 0).sum()) + 6 * int(mjm.neq)
    njmax = rows * nconmax + other + 16
    return {"nconmax": nconmax, "njmax": njmax, "contact_sensor_maxmatch": nconmax}


_IGNORED = {"name_", "names", "text", "stat", "paths", "signature"}


def _array_fields(mjm: mujoco.MjModel) -> list[str]:
    out = []
    for name in dir(mjm):
        if name.startswith("_") or any(name.startswith(p) for p in _IGNORED):
            continue
        try:
            v = getattr(mjm, name)
        except Exception:  # noqa: BLE001
            continue
        if isinstance(v, np.ndarray) and v.dtype.kind in "fiub":
            out.append(name)
    return out


_OPT_FIELDS = ("timestep", "tolerance", "ls_tolerance", "noslip_tolerance", "ccd_tolerance", "gravity",
               "wind", "magnetic", "density", "viscosity", "impratio", "o_margin", "o_solref", "o_solimp",
               "o_friction", "integrator", "cone", "jacobian", "solver", "iterations", "ls_iterations",
               "noslip_iterations", "ccd_iterations", "disableflags", "enableflags")


#: MjModel fields MuJoCo Warp reads only for a feature that an ``opt.enableflags`` bit turns on: where
#: every world leaves the bit off, the worlds need not agree on them (the Warp model carries the first
#: world's).  ``dof_length`` (the velocity norm's weights) is read by island sleeping alone
#: (mujoco_warp/_src/sleep.py; checked against the installed sources in tests/test_warp.py), and it
#: differs by ~1e-17 between pair scenes that differ in their start offset dx0: counted, it would split
#: every dx0 sweep into ~5 Warp models (as measured in an H200's quick reproduction, docs/gpu.md).
ONLY_WITH_FLAG = {"dof_length": int(mujoco.mjtEnableBit.mjENBL_SLEEP)}


def _plan_worlds(models: Sequence[mujoco.MjModel]):
    """Split the worlds into groups that share one Warp model: worlds of a group differ only in
    fields that MuJoCo Warp batches per world.  Returns ``[(indices, {field: per-world values})]``
    (option fields under ``"opt." + name``).  MjModel fields MuJoCo Warp does not carry are ignored,
    and so are those it reads only for a feature every world leaves off (:data:`ONLY_WITH_FLAG`)."""
    require()
    import dataclasses

    from mujoco_warp._src import types as _types  # the field specs: "*" marks a per-world field

    fields_w = dataclasses.fields(_types.Model)
    known = {f.name for f in fields_w}  # MjModel fields MuJoCo Warp does not carry (bvh_aabb...) do not matter
    flags = [int(m.opt.enableflags) for m in models]
    known -= {n for n, bit in ONLY_WITH_FLAG.items() if not any(f & bit for f in flags)}
    def per_world(f) -> bool:  # an array spec whose first dimension is "*"
        return tuple(getattr(f.type, "shape", None) or ())[:1] == ("*",)

    batchable = {f.name for f in fields_w if per_world(f)}
    opt_batchable = {f.name for f in dataclasses.fields(_types.Option) if per_world(f)}
    m0 = models[0]
    fields = _array_fields(m0)
    differ: dict[str, np.ndarray] = {}
    for name in fields:
        if name not in known:
            continue
        vals = [getattr(m, name) for m in models]
        ref, shape = vals[0].tobytes(), vals[0].shape  # equal bytes of one shape: equal values (NaN too)
        if not all(v.shape == shape and v.tobytes() == ref for v in vals[1:]):
            differ[name] = np.stack(vals)
    opt_differ: dict[str, np.ndarray] = {}
    for name in _OPT_FIELDS:
        vals = [np.asarray(getattr(m.opt, name)) for m in models]
        if not all(np.array_equal(v, vals[0]) for v in vals[1:]):
            opt_differ[name] = np.stack(vals)
    split = [n for n in differ if n not in batchable] + [f"opt.{n}" for n in opt_differ if n not in opt_batchable]
    # worlds that agree on every field that cannot be batched share one Warp model
    keys = []
    for b in range(len(models)):
        parts = [differ[n][b].tobytes() for n in split if not n.startswith("opt.")]
        parts += [opt_differ[n[4:]][b].tobytes() for n in split if n.startswith("opt.")]
        keys.append(b"|".join(parts))
    groups = []
    for key in dict.fromkeys(keys):
        idx = np.array([b for b, k in enumerate(keys) if k == key])
        per_world = {n: v[idx] for n, v in differ.items() if n in batchable}
        per_world.update({f"opt.{n}": v[idx] for n, v in opt_differ.items() if n in opt_batchable})
        groups.append((idx, per_world))
    return groups


class _Servos:
    """The CPU model's ``pid`` servos expressed as the Warp model's affine servos, and the set-point
    slew limit applied to the control stream (:mod:`undulate.simulation._warp`'s docstring)."""

    def __init__(self, cpu: mujoco.MjModel, aff: mujoco.MjModel, dt: float, models: Sequence[mujoco.MjModel]):
        """``cpu``: the first scene's model (the layout); ``models``: every scene's (gains and slew
        rates may differ per scene: ``ratio`` and ``rate`` have one row per scene)."""
        pid = [i for i in range(cpu.nactuator) if cpu.actuator_gaintype[i] == mujoco.mjtGain.mjGAIN_PID]
        other = [i for i in range(cpu.nactuator) if i not in pid]
        for i in pid:
            if cpu.actuator_actnum[i] > 1 or float(cpu.actuator_dynprm[i, 0]) > 0:
                raise ParameterError("servo", "without an integral term (ki <= 0) on the 'warp' backend "
                                     "(MuJoCo Warp has no pid actuator)",
                                     mujoco.mj_id2name(cpu, mujoco.mjtObj.mjOBJ_ACTUATOR, i))

        def dst(i: int) -> int:  # the Warp model's input of CPU actuator i (same name)
            return int(aff.actuator_ctrladr[aff.actuator(cpu.actuator(i).name).id])

        adr = cpu.actuator_ctrladr
        self.src_pos = np.array([adr[i] for i in pid], int)
        self.src_vel = self.src_pos + 1
        self.dst = np.array([dst(i) for i in pid], int)
        self.act = np.array([cpu.actuator_actadr[i] if cpu.actuator_actnum[i] == 1 else -1 for i in pid], int)
        self.copy_src, self.copy_dst = np.array([adr[i] for i in other], int), np.array([dst(i) for i in other], int)
        self.nu = aff.nu
        pid = np.array(pid, int)
        self.ratio = np.stack([m.actuator_biasprm[pid, 2] / m.actuator_biasprm[pid, 1] for m in models])  # kv / kp
        self.rate = np.stack([np.where((m.actuator_dynprm[pid, 1] > 0) & (m.actuator_actnum[pid] == 1),
                                       m.actuator_dynprm[pid, 1] * dt, np.inf) for m in models])  # slewmax dt

    def table(self, u: np.ndarray, act0: np.ndarray):
        """Controls ``u`` (nb, k, nu of the CPU model) -> the Warp model's (k, nb, nu) float32 table,
        and the slew states after every step (nb, k, nservo; a view of a step-major array).  ``act0``:
        the slew states at the start (nb, nservo; NaN where a servo has none).  Built step-major, as
        the table is, so each step's rows are contiguous, with slices where the columns are evenly
        spaced (the host's share of a chunk: docs/gpu.md, "The host's share")."""
        nb, k = u.shape[:2]
        ut = u.transpose(1, 0, 2)
        out = np.zeros((k, nb, self.nu), np.float32)
        if self.copy_dst.size:
            out[:, :, _cols(self.copy_dst)] = ut[:, :, _cols(self.copy_src)]
        slewed = _slew_steps(np.ascontiguousarray(ut[:, :, _cols(self.src_pos)]), self.rate, act0)
        out[:, :, _cols(self.dst)] = slewed + self.ratio[None] * ut[:, :, _cols(self.src_vel)]
        return out, slewed.transpose(1, 0, 2)


def _idle_controls(u: np.ndarray, active: np.ndarray | None, nstep: int) -> np.ndarray:
    """The first ``nstep`` steps' controls of ``u`` (nb, k, nu), zero for the scenes outside ``active``
    (set in place).  A scene its rule stopped still steps on the device, its steps thrown away, under
    rows nothing fills once it stopped (and unset in a new buffer): garbage there (inf once cast to
    float32, NaN) could overflow its world's contact capacity, a CapacityError for the whole batch, or
    keep the solver iterating on a GPU."""
    if active is not None and not active.all():
        u[~active, :nstep] = 0.0
    return u[:, :nstep]


def _cols(idx: np.ndarray):
    """``idx`` as a slice where its columns are evenly spaced and ascending (a view, not a gather)."""
    step = int(idx[1] - idx[0]) if idx.size > 1 else 1
    if idx.size and step > 0 and (np.diff(idx) == step).all():
        return slice(int(idx[0]), int(idx[-1]) + 1, step)
    return idx


def slew(target: np.ndarray, rate: np.ndarray, act0: np.ndarray) -> np.ndarray:
    """The slew states after every step: MuJoCo's rule, the state moves toward the command by at
    most ``slewmax dt`` a step, ``s <- s + clip(target - s, -rate, rate)``, from ``act0``.

    ``target``: (nb, k, nservo) commands; ``rate``: (nb, nservo) ``slewmax dt`` (inf: no slew limit,
    the state is the command); ``act0``: (nb, nservo).  Bitwise the step-by-step rule, without a
    Python step per step where it can be skipped: once every state equals its command, the rule
    gives the command itself at each following step whose change is within the rate and exact in
    floating point (``t + (t' - t) == t'``), so those steps are copied whole (a gait within the
    servos' speed is all such steps after the start's ramp)."""
    return _slew_steps(np.ascontiguousarray(target.transpose(1, 0, 2)), rate, act0).transpose(1, 0, 2)


def _slew_steps(target: np.ndarray, rate: np.ndarray, act0: np.ndarray) -> np.ndarray:
    """:func:`slew` on step-major commands (k, nb, nservo) -> step-major states: every step's rows
    contiguous, as the control table is."""
    k = target.shape[0]
    finite = np.isfinite(rate)
    out = np.empty_like(target)
    if not finite.any() or k == 0:
        out[:] = target
        return out
    r = np.where(finite, rate, 0.0)
    d = target[1:] - target[:-1]
    exact = ((np.abs(d) <= r[None]) & (target[:-1] + d == target[1:])) | ~finite[None]
    breaks = np.flatnonzero(~exact.all(axis=(1, 2)))  # step j -> j + 1 not followed exactly
    s = np.where(finite, act0, 0.0)
    i = 0
    while i < k:
        s = np.where(finite, s + np.clip(target[i] - s, -r, r), target[i])
        out[i] = s
        if np.array_equal(s, target[i]):  # on its command: copy the steps that follow exactly
            nxt = np.searchsorted(breaks, i)
            end = int(breaks[nxt]) if nxt < len(breaks) else k - 1  # the last step reached exactly
            out[i + 1:end + 1] = target[i + 1:end + 1]
            s = target[end].copy()
            i = end
        i += 1
    return out


# The timeline (UNDULATE_WARP_TIMELINE): where a Warp model's time goes, chunk by chunk.  Kept in this
# module so that the MuJoCo backend's code hash and the GPU check's CPU reference do not follow it.
TIMELINE_ENV = "UNDULATE_WARP_TIMELINE"
TIMELINE_FLUSH_S = 1.0  # a model's chunks are written at least this often (wall seconds)

_TIMELINE_IDS = itertools.count()
_TIMELINE_LOCK = threading.Lock()


class _Timeline:
    """Where a Warp model's time goes, chunk by chunk (a record for measurements, off unless asked for).

    With ``UNDULATE_WARP_TIMELINE=FILE`` every Warp model (one :class:`undulate.simulation._warp._Group`)
    appends to FILE, as JSON lines, the chunks it stepped: when each began (Unix time, seconds), how long
    its call took (the control table and states up, the steps on the device, the chunk's rows down; on
    Warp's CPU device also the wait for the device lock) and how many steps it had.  Between two chunks
    of one model lies the host's work of its batch (recording, stopping rules, the next control table).

    Why: on an H200 a quick reproduction stepped ~20 small Warp models at once and each
    step took ~8x one model's alone (docs/gpu.md).  From one reproduction's timeline,
    ``benchmarks/bench_warp_timeline.py`` reads how many models stepped at once, how a step's time grew with
    that number, how much of a model's life was the host's, and how many of the models stepping at
    once shared one structure (what gathering them into one model could remove).

    A line is ``{"pid", "group", "structure", "nworld", "device", "label", "chunks": [[start_unix_s,
    wall_s, steps, first], ...]}`` (``first``: the call compiled or captured the model's graphs;
    ``label``: the sweep a gathered batch steps for, ``STUDY/SWEEP-MODE-seedS...``,
    else ""), written each second of a model's stepping and when its batch ends, so a run cut short
    loses at most its last second.  Several processes may append to one file (whole lines, each in one write).
    """

    def __init__(self, structure: tuple, nworld: int, device: str):
        """``structure``: what two models must share to be one, as numbers: the sizes a gathered batch
        shares (nq, nv, nu, na, nsensordata, ngeom) and the time step (last)."""
        self.path = os.environ.get(TIMELINE_ENV) or None
        self.head = {"pid": os.getpid(), "group": next(_TIMELINE_IDS), "structure": list(structure),
                     "nworld": int(nworld), "device": device, "label": BATCH_LABEL.get()}
        self.rows: list[list] = []
        self.written = time.perf_counter()

    def chunk(self, start_unix_s: float, wall_s: float, steps: int, first: bool) -> None:
        """Record a chunk: begun at ``start_unix_s``, ``wall_s`` long, ``steps`` steps."""
        if self.path is None:
            return
        self.rows.append([round(start_unix_s, 6), round(wall_s, 7), int(steps), int(bool(first))])
        if time.perf_counter() - self.written >= TIMELINE_FLUSH_S:
            self.flush()

    def flush(self) -> None:
        """Write the chunks recorded since the last write (one line)."""
        if self.path is None or not self.rows:
            return
        line = json.dumps({**self.head, "chunks": self.rows}, separators=(",", ":")) + "\n"
        self.rows = []
        self.written = time.perf_counter()
        with _TIMELINE_LOCK, open(self.path, "a", encoding="utf-8") as f:
            f.write(line)


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
            # its own stream on a GPU: the groups of threads running side by side (studies, gathered
            # sweeps) overlap on the device instead of queueing on its default stream
            # (UNDULATE_WARP_STREAMS=0: every group on the device's current stream, one thread at a time)
            own = wp.get_device(device).is_cuda and os.environ.get("UNDULATE_WARP_STREAMS", "1") != "0"
            self.stream = wp.Stream(device) if own else None
        self.graphs: list = []  # (steps, captured graph), the longest first; none until captured
        self.bufs = None
        self.stepped = False  # its kernels compiled (a first step taken)
        self.nq, self.nv, self.ns, self.nu = mjm.nq, mjm.nv, mjm.nsensordata, mjm.nu
        self.timeline = _Timeline((mjm.nq, mjm.nv, mjm.nu, mjm.na, mjm.nsensordata, mjm.ngeom,
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
            wp.launch(kernels.set_ctrl, dim=(nw, table.shape[2]), inputs=[table, self.k, self.d.ctrl])
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
        from warp._src.context import runtime  # warp-lang is pinned (the gpu extra)

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


def determinism(device: str = "cuda") -> int:
    """MuJoCo Warp's determinism bitmask for a Warp model on ``device``: ``UNDULATE_WARP_DETERMINISTIC``
    (1: all of it, stable contact order, canonical constraint rows and order-invariant atomic sums;
    0: none), by default on Warp's CPU device and off on a GPU.

    On the CPU device it costs nothing measurable (a pair: 27.0 k against 26.5 k world-steps/s) and the
    kernels run on one thread, so the same inputs give the same results either way.  On a GPU its
    order-invariant atomics are sort-reduce launches whose workspace grows with the launch size times
    the constraint rows: on an H200 it made the pair's steps 8.9x slower at 1 024 worlds
    and 20x at 8 192, and could not allocate at 32 768 worlds nor for one jammed 50-swimmer pack
    (Warp's arrays stop at 2^31 elements).  Off, identical worlds of a jammed pack drift apart on a GPU
    (4 cm in 1 s on an H200, GPU.md): only statistics over runs are comparable there, as between the
    two engines; the Dataset attr ``warp_determinism`` and the sweep identity say which."""
    _, mjw = require()
    from mujoco_warp._src.types import DeterminismType

    on = env_switch("UNDULATE_WARP_DETERMINISTIC", is_cpu_device(device))
    return int(DeterminismType.ALL if on else DeterminismType.NONE)


def _beyond_determinism(error: Exception) -> bool:
    """Whether ``error`` is Warp refusing a deterministic launch's workspace (its sort-reduce buffers
    exceed what a Warp array may hold: measured on an H200 for a jammed pack, and a pair at 32 768 worlds)."""
    text = str(error)
    return (type(error).__name__ == "WarpDeterminismError" or "atomic-update slots" in text
            or "signed 32-bit integer" in text)


STEPS_PER_GRAPH = 16
"""Steps captured in one graph on a GPU (besides the one-step graph for a chunk's remainder): a chunk of
k steps is k // 16 + k % 16 launches, each one Python call on the host (``UNDULATE_WARP_STEPS_PER_GRAPH``).
On Warp's CPU device the default is 1: there the kernels dominate a step (a pair: 70 us a step either
way) and capturing 16 steps costs each new model ~0.4 s."""


def steps_per_graph(device: str = "cuda") -> int:
    """Steps in one captured graph on ``device``: ``UNDULATE_WARP_STEPS_PER_GRAPH``, else
    :data:`STEPS_PER_GRAPH` on a GPU and 1 on Warp's CPU device."""
    return env_count("UNDULATE_WARP_STEPS_PER_GRAPH", 1 if is_cpu_device(device) else STEPS_PER_GRAPH, 1000)


def compile_workers() -> int:
    """Threads that compile a Warp model's kernels at once: ``UNDULATE_WARP_COMPILE_WORKERS``, or
    the CPUs this process may use (1: one module after another, as Warp's first step does)."""
    return env_count("UNDULATE_WARP_COMPILE_WORKERS", usable_cpus())


def _traced_modules(group: "_Group") -> list:
    """The Warp modules (with their block sizes) that one step of ``group``'s model launches,
    found by running MuJoCo Warp's step with every launch of this thread only recorded: on
    throwaway data of the same shapes (the step's own copies and fills land there), with the
    constraint solver's iterations unrolled (a conditional loop would wait for kernels that
    never ran).  The kernels are the same ones the real step launches, since MuJoCo Warp
    specialises them on the model and the data's sizes, which are the group's."""
    wp, mjw = require()
    from . import _warp_kernels as kernels

    from warp._src.context import _normalize_launch_dim  # warp-lang is pinned (the gpu extra)

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

    from warp._src.context import _resolve_launch_block_dim, runtime  # warp-lang is pinned (the gpu extra)

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
    path = os.environ.get("UNDULATE_WARP_STATS")
    if path:
        import json

        with open(path, "a", encoding="utf-8") as f:
            f.write(json.dumps({"first_step_s": seconds, "nworld": nworld, "nv": nv,
                                "steps_per_graph": steps_per_graph}) + "\n")


_OVERFLOW_NAMES = {"NEFC": "njmax (constraint rows per world)", "NJMAX_NNZ": "njmax_nnz",
                   "BROADPHASE": "nconmax (broadphase pairs)", "NARROWPHASE": "nconmax (contacts per world)",
                   "CONTACT_MATCH": "contact_sensor_maxmatch (contacts a contact sensor may match)",
                   "CCD": "ccd iterations", "NVMAX": "nvmax", "EPA_HORIZON": "EPA horizon"}


class WarpRollout:
    """Steps a batch's scenes as the worlds of MuJoCo Warp models (the interface of
    :class:`undulate.simulation._WarmRollout`: ``rollout``, ``warm``, ``close``)."""

    def __init__(self, compiled, affine, options, device: str, reduce: "_Reduction | None" = None):
        """``reduce``: reduce each chunk on the device (:meth:`rollout_samples`) instead of recording
        every step (:meth:`rollout`)."""
        require()
        self.device = device
        self.reduce = reduce
        cpu0 = compiled[0].model
        self.nq, self.nv, self.na = cpu0.nq, cpu0.nv, cpu0.na
        nstate = mujoco.mj_stateSize(cpu0, mujoco.mjtState.mjSTATE_FULLPHYSICS)
        if nstate != 1 + cpu0.nq + cpu0.nv + cpu0.na:
            raise ParameterError("backend", "'mujoco' for this scene (its state has parts the Warp backend "
                                 "does not carry)", "warp")
        self.servos = _Servos(cpu0, affine[0].model, options.timestep_s, [c.model for c in compiled])
        models = []
        for a in affine:
            mjm = a.model
            mjm.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_DIAGEXACT)
            models.append(mjm)
        with _DEVICE_LOCK:
            self.groups = [_Group(models[idx[0]], idx, per_world, device, [models[i] for i in idx], reduce)
                           for idx, per_world in _plan_worlds(models)]
        self.warm = np.zeros((len(compiled), cpu0.nv))
        self._dt = float(options.timestep_s)

    def _control_table(self, cur: np.ndarray, u: np.ndarray, active: np.ndarray | None, nstep: int):
        """The device's control table for ``nstep`` steps of ``u`` from ``cur`` (the servos' slew from
        their states there; scenes outside ``active`` under zero controls) and the slewed set-points
        (:meth:`_Servos.table`)."""
        a0, act_idx = 1 + self.nq + self.nv, self.servos.act
        act0 = np.where(act_idx >= 0, cur[:, a0 + np.maximum(act_idx, 0)] if self.na else 0.0, np.nan)
        return self.servos.table(_idle_controls(u, active, nstep), act0)

    def _step_groups(self, cur: np.ndarray, table: np.ndarray, nstep: int):
        """Step every group ``nstep`` steps from ``cur`` under ``table``: all of them launched first,
        so that on a GPU a batch's Warp models step side by side on their streams, then each one's
        chunk collected (``[(group, what :meth:`_Group.collect` returns)]``, in order)."""
        nq, nv = self.nq, self.nv
        for g in self.groups:
            idx = _cols(g.idx)  # a slice where the group's worlds are evenly spaced (no gathers; the
            # table itself, uncopied, where one group holds every world in order)
            g.launch(cur[idx, 1:1 + nq], cur[idx, 1 + nq:1 + nq + nv], self.warm[idx],
                     np.ascontiguousarray(table[:, idx]), nstep)
        return [(g, g.collect()) for g in self.groups]

    def rollout(self, cur: np.ndarray, u: np.ndarray, st: np.ndarray, sd: np.ndarray, nstep: int,
                active: np.ndarray | None = None):
        """Step every scene ``nstep`` steps from ``cur`` (nb, nstate FULLPHYSICS) under controls ``u``
        (nb, nstep, nu), into ``st`` (nb, nstep, nstate) and ``sd`` (nb, nstep, nsensordata).
        Scenes outside ``active`` stay at ``cur`` (their sensor rows zero)."""
        nq, nv, na = self.nq, self.nv, self.na
        q0, v0, a0 = 1, 1 + nq, 1 + nq + nv
        act_idx = self.servos.act
        table, slewed = self._control_table(cur, u, active, nstep)
        t0 = cur[:, :1]  # the clock stays float64 on the host
        for g, (q, v, s, warm, overflow) in self._step_groups(cur, table, nstep):
            idx = _cols(g.idx)
            if overflow.any():
                self._overflow(g.idx, overflow)
            st[idx, :nstep, q0:q0 + nq] = q
            st[idx, :nstep, v0:v0 + nv] = v
            sd[idx, :nstep] = s
            self.warm[idx] = warm
        if na:
            st[:, :nstep, a0:] = cur[:, None, a0:]
            has = act_idx >= 0
            st[:, :nstep, _cols(a0 + act_idx[has])] = slewed[:, :, _cols(np.flatnonzero(has))]
        st[:, :nstep, 0] = t0 + self._dt * (1 + np.arange(nstep))[None]
        if active is not None:
            st[~active], sd[~active] = cur[~active, None], 0.0
        return st, sd

    def rollout_samples(self, cur: np.ndarray, u: np.ndarray, nstep: int, active: np.ndarray | None = None):
        """Step every scene ``nstep`` steps (a multiple of the sample interval) from ``cur`` under
        controls ``u``, reduced on the device: only what the recorder keeps comes back.  Returns the
        FULLPHYSICS states (nb, ns, nstate) and sensors (nb, ns, nsensordata) at each interval's last
        step, the interval's deepest penetration (nb, ns), mean pair and wall force magnitudes
        (nb, ns, npair) and (nb, ns, nwall), and per scene the first bad step (-1: none) and what
        was bad there (1 huge or non-finite state, 2 interpenetration beyond the bound).  Scenes
        outside ``active`` stay at ``cur`` (their sensor rows zero, nothing bad)."""
        r = self.reduce
        sps = r.sps
        nq, nv, na = self.nq, self.nv, self.na
        q0, v0, a0 = 1, 1 + nq, 1 + nq + nv
        nb, ns = cur.shape[0], nstep // sps
        act_idx = self.servos.act
        table, slewed = self._control_table(cur, u, active, nstep)
        st = np.empty((nb, ns, cur.shape[1]))
        sd = np.empty((nb, ns, self.groups[0].ns))
        pn = np.empty((nb, ns))
        fp, fw = np.empty((nb, ns, len(r.pair_adr))), np.empty((nb, ns, len(r.wall_adr)))
        code = np.zeros(nb, dtype=np.int64)
        for g, (q, v, s, p, f_pair, f_wall, bad, warm, overflow) in self._step_groups(cur, table, nstep):
            idx = _cols(g.idx)
            if overflow.any():
                self._overflow(g.idx, overflow)
            st[idx, :, q0:q0 + nq], st[idx, :, v0:v0 + nv], sd[idx] = q, v, s
            pn[idx], fp[idx], fw[idx], code[idx] = p, f_pair, f_wall, bad
            self.warm[idx] = warm
        rows = np.arange(sps - 1, nstep, sps)
        if na:
            st[:, :, a0:] = cur[:, None, a0:]
            has = act_idx >= 0
            st[:, :, a0 + act_idx[has]] = slewed[:, rows][:, :, has]
        st[:, :, 0] = cur[:, :1] + self._dt * (1 + rows)[None]
        if active is not None:
            st[~active], sd[~active], pn[~active], code[~active] = cur[~active, None], 0.0, 0.0, 0
            fp[~active], fw[~active] = 0.0, 0.0
        return st, sd, pn, fp, fw, np.where(code > 0, code // 4 - 1, -1), code % 4

    def _overflow(self, idx, overflow) -> None:
        _, mjw = require()
        from mujoco_warp._src.types import OverflowType

        w = int(np.flatnonzero(overflow)[0])
        bits = int(overflow[w])
        names = [_OVERFLOW_NAMES.get(f.name, f.name) for f in OverflowType
                 if f.name not in ("NONE", "ALL") and bits & int(f) and f.value]
        cap = self.groups[0].cap
        raise CapacityError(
            f"MuJoCo Warp world {int(idx[w])} overflowed: {', '.join(names)} "
            f"(allocated per world: nconmax {cap['nconmax']}, njmax {cap['njmax']}, "
            f"contact_sensor_maxmatch {cap['contact_sensor_maxmatch']}); the results would be wrong, "
            f"so the run stops (undulate.simulation._warp.capacities sizes them from the scene)")

    def close(self) -> None:
        for g in self.groups:
            g.timeline.flush()
        self.groups = []
