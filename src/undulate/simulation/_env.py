"""What the engines share without importing either: which devices are Warp's CPU device and the CPUs
this process may use (:mod:`undulate.execution`, where the settings are read), and the label of the
gathered batch stepping in this context."""

from __future__ import annotations

import contextvars

from ..execution import is_cpu_device, usable_cpus

__all__ = ["BATCH_LABEL", "is_cpu_device", "usable_cpus"]

BATCH_LABEL: contextvars.ContextVar[str] = contextvars.ContextVar("undulate_batch_label", default="")
"""What a gathered batch steps for (its sweep: ``STUDY/SWEEP``, :attr:`undulate.simulation.Gather.label`),
set while it steps; the Warp backend's timeline names its models by it
(:class:`undulate.simulation._warp_timeline.Timeline`)."""
