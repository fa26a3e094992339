"""Step scenes in C with ``mujoco.rollout`` and record an ``xarray.Dataset``.

The per-step loop runs entirely inside MuJoCo's C rollout.  Python only
prepares the open-loop controls of a chunk of steps (the gait's set-points
and the perturbation forces), hands the chunk to ``rollout`` and decimates
its output to the recording rate.  Chunks bound memory for long runs and
large groups.

The constraint solver is warm-started from the previous step's
accelerations, as in a plain ``mj_step`` loop, and each scene's warm start is
carried from one ``rollout`` call to the next (:class:`_WarmRollout`): results
are bitwise independent of the chunk size and of batching, and equal to a
plain ``mj_step`` loop from a fresh ``MjData`` (``tests/test_simulation.py``).

Two engines step the scenes (``SimOptions.backend``), both behind one interface
(:class:`~undulate.simulation._engines.Backend`): MuJoCo's C engine
(the default; everything above holds bitwise) and MuJoCo Warp
(:mod:`undulate.simulation._warp`: every scene of a batch one world of one model, on a
GPU or Warp's CPU device, float32; agreement with the default engine is
measured in docs/gpu.md, not bitwise).  :class:`Gather` lets the runs of a
sweep, each on its own thread, reach Warp as one batch.

Where the code lives: :mod:`._run` (:func:`simulate`, :func:`simulate_batch`), :mod:`._batch` (a
batch planned: time step, engine, compiled scenes, chunks), :mod:`._stepper` (chunks stepped and
turned into samples), :mod:`._control_loop` (closed-loop chunks), :mod:`._engines` (the
:class:`Backend` interface and its registry), :mod:`._mujoco` and :mod:`._warp` (the engines),
:mod:`._record` (recorders), :mod:`._resolve` and :mod:`._compile` (options and models).

Recorded variables: :mod:`undulate.schema` (names, dims, units, long
names; shared with the robot logger and the tracker).

Forces are interval means: ``sum(F * sample_interval)`` is the exact
time-integral over the run (every step contributes).
"""

from __future__ import annotations

from .._xrcompat import install as _lazy_dask
from ..schema import scene_attrs, variable
from ._backend import backend_attrs, check_backend, default_backend, use_backend, warp_processes
from ._checkpoint import Checkpoint
from ._compile import controls
from ._engines import Backend, Rollout, SampledRollout, backend
from ._mujoco import _initial_state  # noqa: F401 - the benchmarks (bench_gpu_check, bench_warp_side_by_side) read it here
from ._gather import Gather
from ._mujoco import _state_layout as state_layout
from ._record import RECORDABLE
from ._resolve import RK4_DAMPING_STEP, compile_scene, resolve_options
from ._run import simulate, simulate_batch

_lazy_dask()  # no Dask import for NumPy-only data (undulate._xrcompat)

__all__ = ["simulate", "simulate_batch", "Checkpoint", "compile_scene", "controls", "resolve_options", "RECORDABLE",
           "use_backend", "default_backend", "check_backend", "backend_attrs", "warp_processes", "Gather",
           "Backend", "Rollout", "SampledRollout", "backend", "scene_attrs", "variable", "RK4_DAMPING_STEP",
           "state_layout"]
