"""Runs of several threads stepped as one batch (:class:`Gather`): how a sweep's runs reach the Warp
backend as the worlds of one model."""

from __future__ import annotations

import contextvars
import json
from collections.abc import Callable

import xarray as xr

from .. import _walltime
from ..execution import carry_into
from ..params import SimOptions
from ._checkpoint import Checkpoint, as_list
from ._engines import backend
from ._env import BATCH_LABEL
from ._resolve import resolve_options

class _NoStop:
    """The stopping rule of a scene that has none, in a gathered batch (it never ends a run)."""

    rule = ""

    def __call__(self, blocks):
        return None


class _Request:
    def __init__(self, scenes, options, stop, run, start=None):
        self.scenes, self.options, self.stop, self.run = scenes, options, stop, run
        self.start = as_list(start)
        self.result = self.error = None
        self.done = False
        self.physics = (0.0, 0)
        self.compiled = None  # (push, the first scene's CompiledScene): what grouping it compiled

    def rules(self) -> list:
        if self.stop is None:
            return [_NoStop() for _ in self.scenes]
        return [self.stop] if callable(self.stop) else list(self.stop)

    def start_key(self) -> tuple[bool, float | None]:
        """(whether the call can join a batch, its checkpoints' one time in s or None from rest):
        calls that go on from checkpoints join only calls whose checkpoints have the same time
        (a batch steps from one time); a call whose own checkpoints are malformed or of several
        times runs alone (it raises there, naming ``start``)."""
        if self.start is None:
            return True, None
        if len(self.start) != len(self.scenes) or not all(isinstance(c, Checkpoint) for c in self.start):
            return False, None
        times = {round(c.time_s, 9) for c in self.start}
        return len(times) == 1, min(times)


class Gather:
    """Runs the simulations of several threads as one batch: every thread's
    :func:`simulate_batch` call waits until each live thread has either called it or finished,
    then the calls are stepped together, one batch per structure and options (on the Warp
    backend: one world per scene).  Each call returns its own Datasets, each bitwise what the
    same batch would give (:func:`simulate_batch`: a scene's run does not depend on the others,
    on the MuJoCo backend bitwise, on Warp to float32 rounding of the solver's reductions).

    Used by the sweep runner for the Warp backend (:func:`undulate.sweep.run_sweep`): a study's
    runs, each in its own thread, reach the GPU together.  Calls that go on from checkpoints
    (``start``) are gathered with the calls whose checkpoints have the same time (e.g. the packing
    study's stopped runs continued, :func:`undulate.studies.packing.packing_continue`).  Calls with
    ``out``, ``controller`` or ``progress`` run at once, alone.  If a gathered batch fails (one scene
    diverges), its calls are run again one at a time so that only the failing one raises."""

    def __init__(self, n_threads: int, progress: Callable[[float, float, int], None] | None = None,
                 label: str = ""):
        """``progress``: called as ``progress(done, total, worlds)`` while a batch steps (after each
        of its chunks): the simulated world-seconds done and in all of the batches stepping now, and
        their worlds (the sweep's progress display, :meth:`undulate.sweep._progress.Progress.stepping`).
        ``label``: what the batches step for (:data:`BATCH_LABEL`; the sweep runner's ``STUDY/SWEEP``)."""
        import threading

        self.label = str(label)
        self.live = int(n_threads)
        self.pending: list[_Request] = []
        self.cond = threading.Condition()
        self.batches: list[int] = []  # scenes per batch stepped (for reports and tests)
        self.progress = progress
        self._stepping: dict[int, tuple[float, float, int]] = {}  # group -> (done_s, total_s, worlds)

    def _report(self, group: int, worlds: int) -> Callable[[float, float], None] | None:
        """The ``progress(done_s, total_s)`` hook of one group's batch (None without a display)."""
        if self.progress is None:
            return None

        def hook(done_s: float, total_s: float) -> None:
            with self.cond:
                self._stepping[group] = (done_s * worlds, total_s * worlds, worlds)
                done, total, n = (sum(v[i] for v in self._stepping.values()) for i in range(3))
            self.progress(done, total, n)

        return hook

    def submit(self, scenes, options, stop, run, start=None) -> list[xr.Dataset]:
        """Wait for the other threads, then step the calls together; ``run(scenes, options, stop=,
        progress=, start=)`` steps one batch now (:func:`undulate.simulation._run._simulate_batch_now`)."""
        req = _Request(scenes, options or SimOptions(), stop, run, start)
        with self.cond:
            self.pending.append(req)
            if len(self.pending) < self.live:
                while not req.done:
                    self.cond.wait()
                flush = None
            else:
                flush, self.pending = self.pending, []
        if flush is not None:
            self._run(flush)
        if req.error is not None:
            raise req.error
        _walltime.report(*req.physics)
        return req.result

    def thread_done(self) -> None:
        """A thread leaves: its calls are all made (call once per thread, also when it raised)."""
        with self.cond:
            self.live -= 1
            flush = None
            if self.pending and len(self.pending) >= self.live:
                flush, self.pending = self.pending, []
        if flush is not None:
            self._run(flush)

    def _run(self, reqs: list[_Request]) -> None:
        from concurrent.futures import ThreadPoolExecutor

        try:
            groups = _gather_groups(reqs)
            if len(groups) == 1:
                self._run_group(groups[0])
            else:  # one thread per structure: on a GPU each steps on its own stream, side by side
                with ThreadPoolExecutor(len(groups), thread_name_prefix="undulate-gather") as pool:
                    for f in [pool.submit(self._run_group, g) for g in groups]:
                        f.result()
        except BaseException as e:  # noqa: BLE001 - every waiting thread must learn of it
            for r in reqs:
                if r.result is None and r.error is None:
                    r.error = e
        finally:
            with self.cond:
                for r in reqs:
                    r.done = True
                self.cond.notify_all()

    def _context(self) -> contextvars.Context:
        """A fresh context for a batch's call: none of the calling threads' variables but the label and
        the execution settings in effect (:func:`undulate.execution.carry_into`)."""
        ctx = contextvars.Context()
        ctx.run(BATCH_LABEL.set, self.label)
        carry_into(ctx)
        return ctx

    def _run_group(self, group: list[_Request]) -> None:
        """Step one group's calls as one batch; if it fails, each call alone (only the failing ones raise)."""
        scenes = [sc for r in group for sc in r.scenes]
        rules = [rule for r in group for rule in r.rules()]
        starts = None if group[0].start is None else [c for r in group for c in r.start]
        with self.cond:
            self.batches.append(len(scenes))
            hook = self._report(len(self.batches), len(scenes))
        try:
            with _walltime.meter() as tally:  # this batch's physics, shared among its calls
                dss = self._context().run(group[0].run, scenes, group[0].options, stop=rules, progress=hook,
                                          start=starts, compiled=_compiled(group))
        except Exception:  # noqa: BLE001 - isolate the failing call
            for r in group:
                try:
                    with _walltime.meter() as tally:
                        r.result = self._context().run(r.run, r.scenes, r.options, stop=r.stop, start=r.start)
                    r.physics = tally.read()
                except Exception as e:  # noqa: BLE001
                    r.error = e
            return
        sec, steps = tally.read()
        i = 0
        for r in group:
            n = len(r.scenes)
            r.result, i = dss[i:i + n], i + n
            r.physics = (sec * n / len(scenes), steps * n // len(scenes))


def _compiled(group: list[_Request]) -> dict[int, tuple]:
    """``{index in the batch's scenes: (push, CompiledScene)}``: the scenes grouping compiled."""
    out, i = {}, 0
    for r in group:
        if r.compiled is not None:
            out[i] = r.compiled
        i += len(r.scenes)
    return out


def _gather_groups(reqs: list[_Request]) -> list[list[_Request]]:
    """Calls that can be stepped as one batch: same resolved options and one structure (the
    compiled models' sizes), for closed-loop scenes one gait, controller and link count, and the
    same start (from rest, or checkpoints of one time: :meth:`_Request.start_key`)."""
    keys = []
    for r in reqs:
        opts = [resolve_options(sc, r.options) for sc in r.scenes]
        o = opts[0]
        push = any(sc.forces_N is not None for sc in r.scenes)
        cs = backend(o.backend).compile(r.scenes[0], o, push=push, loads=r.scenes[0].controller.closed_loop)
        r.compiled = (push, cs)  # the batch's plan takes it rather than compiling the scene again
        m = cs.model
        closed = r.scenes[0].controller.closed_loop
        joins, start_s = r.start_key()
        joins = joins and len({x.timestep_s for x in opts}) == 1
        keys.append((json.dumps(o.to_dict(), sort_keys=True, default=str), joins,
                     (m.nq, m.nv, m.nu, m.na, m.nsensordata, m.ngeom), r.scenes[0].forces_N is not None,
                     repr((r.scenes[0].gait, r.scenes[0].controller, r.scenes[0].geometry.n_links)) if closed else "",
                     start_s))
    out = []
    for key in dict.fromkeys(keys):
        group = [r for r, k in zip(reqs, keys) if k == key]
        if not key[1]:  # a call whose own scenes need different time steps or start times: alone (raises there)
            out += [[r] for r in group]
        else:
            out.append(group)
    return out



def _gathering() -> "Gather | None":
    import threading

    return getattr(threading.current_thread(), "undulate_gather", None)
