"""How long a simulation will take, and a progress bar for long ones (``undulate simulate``).

The estimate is linear: the wall time of the first chunks of stepping (about
:data:`CALIBRATE_S` seconds of it, at least one chunk, compilation excluded)
per simulated second, times the requested duration.  :class:`RunMonitor` is
a ``progress`` callable for :func:`undulate.simulation.simulate`: it is called
between chunks (never in the per-step loop) and only reads a clock, so the
results are bitwise those of a run without it, and it holds O(1) memory.
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable, TextIO

CALIBRATE_S = 1.0
"""Wall seconds of stepping the estimate is measured on (at least one chunk)."""
ANNOUNCE_S = 60.0
"""Runs estimated to take longer than this (wall s) print the estimate."""
BAR_S = 20.0
"""Runs estimated to take longer than this (wall s) show a progress bar."""
CALIBRATION_SAMPLES = 20_000
""":func:`estimate_compute_time` simulates at most this many samples (bounds its file)."""


def format_duration(seconds: float) -> str:
    """``"45 s"``, ``"3 min 20 s"``, ``"2 h 14 min"``, ``"5 d 3 h"``."""
    s = max(0.0, float(seconds))
    if s < 10:
        return f"{s:.1f} s"
    s = int(round(s))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60} s"
    m = int(round(s / 60))
    if m < 24 * 60:
        return f"{m // 60} h {m % 60} min"
    h = int(round(s / 3600))
    return f"{h // 24} d {h % 24} h"


def _simulated(s: float) -> str:
    return f"{s:.0f}" if s >= 100 else f"{s:.3g}"


@dataclasses.dataclass(frozen=True)
class Estimate:
    """A run's compute time, extrapolated linearly from its first ``measured_on_s`` simulated seconds."""

    wall_per_simulated_s: float
    """Wall seconds per simulated second, as measured."""
    measured_on_s: float
    """Simulated seconds the rate was measured on."""
    total_s: float
    """Simulated seconds of the whole run."""

    @property
    def seconds(self) -> float:
        """Estimated wall seconds of stepping the whole run."""
        return self.wall_per_simulated_s * self.total_s

    def line(self) -> str:
        return (f"estimated compute time: {format_duration(self.seconds)} ({self.wall_per_simulated_s:.2g} s per "
                f"simulated s, measured on the first {_simulated(self.measured_on_s)} s)")


class _Calibrated(Exception):
    """Ends a calibration run (raised from :class:`RunMonitor` by :func:`estimate_compute_time`)."""


class RunMonitor:
    """``progress(done_s, total_s)`` for :func:`undulate.simulation.simulate`.

    The first call (t = 0, once the scene is compiled) starts the clock.
    Once ``calibrate_s`` wall seconds of stepping have passed (or the run has
    ended) it sets :attr:`estimate`, writes its line to ``stream`` when the
    run is estimated to take longer than ``announce_s``, and from then on
    shows a tqdm bar on ``stream`` (simulated seconds) when it is estimated
    to take longer than ``bar_s`` (``bar=False``: never).  Close it (or use it
    as a context manager) to end the bar.
    """

    def __init__(self, *, calibrate_s: float | None = None, announce_s: float | None = None,
                 bar_s: float | None = None, bar: bool = True, stream: TextIO | None = None,
                 clock: Callable[[], float] = time.perf_counter):
        # None: the module's thresholds (read now, so a test can change them)
        self.calibrate_s = CALIBRATE_S if calibrate_s is None else calibrate_s
        self.announce_s = ANNOUNCE_S if announce_s is None else announce_s
        self.bar_s = BAR_S if bar_s is None else bar_s
        self.show_bar = bar
        self.stream, self.clock = stream, clock
        self.estimate: Estimate | None = None
        self.t0: float | None = None
        self.elapsed = 0.0  # wall s of stepping so far
        self.done_s = 0.0
        self.stop_when_calibrated = False
        self._bar = None

    def __call__(self, done_s: float, total_s: float) -> None:
        now = self.clock()
        if self.t0 is None:
            self.t0 = now
            return
        self.elapsed, self.done_s = now - self.t0, done_s
        if self.estimate is None and done_s > 0 and (self.elapsed >= self.calibrate_s or done_s >= total_s):
            self.estimate = Estimate(self.elapsed / done_s, done_s, total_s)
            if self.stop_when_calibrated:
                raise _Calibrated
            self._announce(done_s, total_s)
        if self._bar is not None:
            self._bar.update(done_s - self._bar.n)

    def _announce(self, done_s: float, total_s: float) -> None:
        stream = self.stream if self.stream is not None else sys.stderr
        if self.estimate.seconds > self.announce_s:
            print(self.estimate.line(), file=stream, flush=True)
        if self.show_bar and self.estimate.seconds > self.bar_s and done_s < total_s:
            from tqdm import tqdm

            tty = getattr(stream, "isatty", lambda: False)()
            self._bar = tqdm(total=total_s, initial=done_s, file=stream, mininterval=1.0 if tty else 30.0,
                             bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} simulated s [{elapsed}<{remaining}]")

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> "RunMonitor":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def estimate_compute_time(scene, options, *, calibrate_s: float | None = None,
                          dir: str | os.PathLike | None = None) -> Estimate:
    """Estimate the compute time of ``simulate(scene, options, out=...)`` from its first chunks.

    Steps the run itself (streamed to a temporary file in ``dir``, default
    the system's temporary folder, which is removed)
    for about ``calibrate_s`` wall seconds (default :data:`CALIBRATE_S`), at least one chunk, and at most
    :data:`CALIBRATION_SAMPLES` samples, and extrapolates linearly to
    ``options.duration_s``.  Raises what :func:`~undulate.simulation.simulate`
    raises (:class:`~undulate.errors.DivergenceError` for a run that blows up
    that early).
    """
    from .simulation import simulate

    cap = CALIBRATION_SAMPLES / options.sample_rate_hz
    first = options if options.duration_s <= cap else dataclasses.replace(options, duration_s=cap)
    mon = RunMonitor(calibrate_s=calibrate_s, bar=False)
    mon.stop_when_calibrated = True
    with tempfile.TemporaryDirectory(prefix=".undulate-estimate-", dir=dir) as d:
        try:
            simulate(scene, first, out=Path(d) / "calibration.nc", progress=mon).close()
        except _Calibrated:
            pass
    est = mon.estimate
    if est is None:  # pragma: no cover - simulate always reports its end
        raise RuntimeError("the calibration run reported no progress")
    if not math.isfinite(est.wall_per_simulated_s):  # pragma: no cover
        raise RuntimeError("the calibration run could not be timed")
    return Estimate(est.wall_per_simulated_s, est.measured_on_s, float(options.duration_s))
