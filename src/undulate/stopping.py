"""Stopping rules: end a run once its answer is decided (``simulate(..., stop=...)``).

A rule is a frozen dataclass (a stable ``repr``: bound to a sweep function it
is part of the sweep's identity, so changing it recomputes the runs).  Its
:meth:`monitor` makes the callable :func:`undulate.simulation.simulate_batch`
calls between chunks with the new samples; the monitor keeps running sums
per period or batch only, so its memory does not grow with the run.

* :class:`SteadyStop` -- pair-type runs: stop once the steady-state rule
  (``observables.steady_state``: the last ``window`` period means of
  ``dx/scale`` within ``tol`` of their mean) has held for ``extra_periods``
  more periods, for **every** pair of swimmers (so for whichever neighbours
  the analysis picks), with the lateral order of the period-mean ``y``
  unchanged over those periods, and the offsets' trend over those periods,
  carried on to the end of the full run, moving them by at most
  ``drift_frac * tol`` (a slowly creeping offset satisfies the steady rule
  at every window yet ends elsewhere: it runs on).  With ``leave`` set it
  also stops a pair that has left its state (moved more than ``leave`` from
  its offset before ``leave_after_s`` over ``window`` periods and still
  moving): a pair pulled apart by a force.
* :class:`PhaseStop` -- closed-loop pairs: stop once every swimmer pair's
  phase difference has stayed within ``tol_rad`` of its circular mean for
  ``hold_s + extra_s`` (the lock the run measures, held ``extra_s`` longer),
  with no trend that would move it by the run's end, the lateral order
  unchanged and, where positions are free, the offsets steady by
  :class:`SteadyStop`'s rule.
* :class:`ExcessStop` -- packing probes: stop once the mean joint error after
  ``skip_s`` is above or below a level with one-sided confidence
  ``confidence`` (batch means over ``batch_s``, their standard error, Student t).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import special as _special  # stdtrit: what scipy.stats.t.ppf evaluates, without importing scipy.stats

from .errors import ParameterError
from .params import _count, _nonneg, _positive

__all__ = ["SteadyStop", "PhaseStop", "ExcessStop"]


class _Periods:
    """Running period sums of one scene's per-swimmer series (the half-open periods of
    ``observables.period_average``: period k holds t in (kT, (k+1)T]; t = 0 starts the clock)."""

    def __init__(self, period_s: float, keep: int):
        self.T, self.keep = float(period_s), int(keep)
        self.sums: dict[int, np.ndarray] = {}
        self.counts: dict[int, int] = {}
        self.means: list[np.ndarray] = []  # completed periods, the last ``keep`` only
        self.n_done = 0
        self.t_last = 0.0

    def add(self, t: np.ndarray, values: np.ndarray) -> None:
        k = np.ceil(t / self.T - 1e-9).astype(int) - 1
        for kk in np.unique(k[k >= self.n_done]):
            sel = k == kk
            self.sums[kk] = self.sums.get(kk, 0.0) + values[sel].sum(axis=0)
            self.counts[kk] = self.counts.get(kk, 0) + int(sel.sum())
        if len(t):
            self.t_last = float(t[-1])
        n_full = int(math.floor(self.t_last / self.T + 1e-9))
        while self.n_done < n_full:
            kk = self.n_done
            self.means.append(self.sums.pop(kk) / self.counts.pop(kk))
            self.means = self.means[-self.keep:]
            self.n_done += 1


@dataclass(frozen=True)
class SteadyStop:
    """Stop a pair-type run once the steady rule has held ``extra_periods`` more periods.

    ``tol`` (on ``dx/scale``; ``scale`` = lambda, or L for the standing wave)
    and ``window`` (periods) are the steady-state rule's; ``min_periods``:
    never before this many whole periods (what else the run measures needs them);
    ``drift_frac``: the least-squares trend of each offset's last
    ``window + extra_periods`` period means, times the periods left to the full
    run's end, must stay within ``drift_frac * tol``; ``spread_frac``: each of
    those windows must lie within ``spread_frac * tol`` of its mean (a margin,
    so that a noisy offset that meets the rule by a hair at the stop, and might
    not at the full run's end, runs on).
    """

    tol: float = 0.01
    window: int = 3
    extra_periods: int = 2
    min_periods: int = 6
    drift_frac: float = 0.5
    spread_frac: float = 0.5
    leave: float = math.inf
    """Also stop a run whose pair has *left* its state: once, for some swimmer pair, each of the last
    ``window`` period means of dx/scale lies more than ``leave`` from its period mean just before
    ``leave_after_s`` and their range exceeds ``tol`` (still moving).  Such a run is broken apart
    by any rule that reads a settled offset; it would only move on.  ``inf``: never."""
    leave_after_s: float = 0.0

    def __post_init__(self):
        _nonneg("tol", self.tol)
        _count("window", self.window, 1)
        _count("extra_periods", self.extra_periods, 0)
        _count("min_periods", self.min_periods, 0)
        _nonneg("drift_frac", self.drift_frac)
        _nonneg("spread_frac", self.spread_frac)
        if self.leave != math.inf:  # inf: never
            _positive("leave", self.leave)
        _nonneg("leave_after_s", self.leave_after_s, "s")

    @property
    def rule(self) -> str:
        return (f"SteadyStop(tol={self.tol:g}, window={self.window}, extra_periods={self.extra_periods}, "
                f"min_periods={self.min_periods}, drift_frac={self.drift_frac:g}, spread_frac={self.spread_frac:g}): "
                f"stop once, for every swimmer pair, the last {self.window} period means of dx/scale lie within "
                f"{self.spread_frac * self.tol:g} of their mean in "
                f"each of {self.extra_periods + 1} consecutive windows, the lateral order unchanged, and their "
                f"trend carried to the end of the run moves them by <= {self.drift_frac * self.tol:g}"
                + ("" if not math.isfinite(self.leave) else
                   f"; or once some pair's last {self.window} period means of dx/scale each lie more than "
                   f"{self.leave:g} from its period mean before t = {self.leave_after_s:g} s and span more "
                   f"than {self.tol:g} (left its state, still moving)"))

    def left(self, x_means: np.ndarray, before: np.ndarray) -> bool:
        """Whether some pair has left its state: ``x_means`` the last period means ``(periods,
        swimmers)`` of x / scale, ``before`` the swimmers' period mean just before ``leave_after_s``."""
        if not math.isfinite(self.leave) or len(x_means) < self.window:
            return False
        x = np.asarray(x_means)[-self.window:]
        i, j = np.triu_indices(x.shape[1], 1)
        d, d0 = x[:, j] - x[:, i], np.asarray(before)[j] - np.asarray(before)[i]
        away = (np.abs(d - d0) > self.leave).all(axis=0)
        moving = np.ptp(d, axis=0) > self.tol
        return bool((away & moving).any())

    def monitor(self, period_s: float, scale_m: float, end_s: float) -> "_SteadyMonitor":
        """The callable for ``simulate(..., stop=)``: ``end_s`` is the full run's duration."""
        return _SteadyMonitor(self, period_s, scale_m, end_s)

    def decided(self, x_means: np.ndarray, y_means: np.ndarray, periods_left: float = 0.0) -> bool:
        """The rule on period means ``(periods, swimmers)`` of x / scale and y (the last ones), with
        ``periods_left`` periods to the end of the full run."""
        n = self.window + self.extra_periods
        if len(x_means) < n:
            return False
        x, y = np.asarray(x_means)[-n:], np.asarray(y_means)[-n:]
        i, j = np.triu_indices(x.shape[1], 1)
        d = x[:, j] - x[:, i]  # (periods, pairs)
        for s in range(self.extra_periods + 1):
            w = d[s:s + self.window]
            if (np.abs(w - w.mean(axis=0)) > self.spread_frac * self.tol).any():
                return False
        order = np.argsort(y, axis=1, kind="stable")
        if not (order == order[-1]).all():
            return False
        slope = np.polyfit(np.arange(n, dtype=float), d, 1)[0]  # per period, each pair
        return bool((np.abs(slope) * periods_left <= self.drift_frac * self.tol).all())


class _SteadyMonitor:
    def __init__(self, rule: SteadyStop, period_s: float, scale_m: float, end_s: float):
        self.r, self.scale, self.end_s = rule, float(scale_m), float(end_s)
        keep = rule.window + rule.extra_periods
        self.x: list[_Periods] = []
        self.y: list[_Periods] = []
        self.period_s, self.keep = period_s, keep
        self.rule = rule.rule
        # the period whose mean "before" is: the last that ends by leave_after_s (None: not yet seen)
        self.k_before = int(math.floor(rule.leave_after_s / period_s + 1e-9)) - 1
        self.before: list[np.ndarray] | None = None

    def __call__(self, blocks: list[dict]) -> str | None:
        if not self.x:
            self.x = [_Periods(self.period_s, self.keep) for _ in blocks]
            self.y = [_Periods(self.period_s, self.keep) for _ in blocks]
        for b, blk in enumerate(blocks):
            self.x[b].add(blk["time"], blk["x"] / self.scale)
            self.y[b].add(blk["time"], blk["y"])
        if math.isfinite(self.r.leave) and self.before is None and self.k_before >= 0:
            back = self.x[0].n_done - self.k_before  # how far back the before-period's mean now is
            if 1 <= back <= len(self.x[0].means):
                self.before = [px.means[-back] for px in self.x]
        if self.before is not None and self.x[0].n_done >= self.k_before + 1 + self.r.window:
            if any(self.r.left(px.means, b) for px, b in zip(self.x, self.before)):
                return f"left its state by t = {self.x[0].n_done * self.period_s:g} s"
        if self.x[0].n_done < self.r.min_periods:
            return None
        left = max(0.0, self.end_s / self.period_s - self.x[0].n_done)
        if all(self.r.decided(px.means, py.means, left) for px, py in zip(self.x, self.y)):
            return f"steady by t = {self.x[0].n_done * self.period_s:g} s ({self.r.extra_periods} extra periods)"
        return None


@dataclass(frozen=True)
class PhaseStop:
    """Stop a closed-loop pair-type run once its phase lock is decided.

    ``tol_rad`` and ``hold_s`` are the lock rule's (:func:`undulate.phases.time_to_lock`:
    every sample of the last ``hold_s`` within ``tol_rad`` of their circular mean).  The run
    stops once, for every swimmer pair, the wrapped phase difference has stayed within
    ``spread_frac * tol_rad`` of its circular mean over the last ``hold_s + extra_s`` (a
    margin: the lock time the run reports is measured against its final value at
    ``tol_rad``, and a final value that moves a little later must not move it; locked at least
    ``extra_s`` before the window the run's final value is taken over), its least-squares
    trend over that window, carried to the end of the full run, moves it by at most
    ``drift_frac * tol_rad`` (a slowly creeping lock runs on), the
    lateral order of the swimmers is unchanged over it, and the offsets along the channel
    meet ``steady`` (period means; held positions meet it trivially); never before
    ``min_s``.  Memory: the last ``hold_s + extra_s`` of samples only.
    """

    tol_rad: float = 0.15
    hold_s: float = 10.0
    extra_s: float = 10.0
    min_s: float = 20.0
    drift_frac: float = 0.5
    spread_frac: float = 0.5
    steady: SteadyStop = SteadyStop()

    def __post_init__(self):
        _positive("tol_rad", self.tol_rad, "rad")
        _positive("hold_s", self.hold_s, "s")
        _nonneg("extra_s", self.extra_s, "s")
        _nonneg("min_s", self.min_s, "s")
        _nonneg("drift_frac", self.drift_frac)
        _nonneg("spread_frac", self.spread_frac)
        if not isinstance(self.steady, SteadyStop):
            raise ParameterError("steady", "a SteadyStop", type(self.steady).__name__)

    @property
    def rule(self) -> str:
        return (f"PhaseStop(tol_rad={self.tol_rad:g}, hold_s={self.hold_s:g}, extra_s={self.extra_s:g}, "
                f"min_s={self.min_s:g}, drift_frac={self.drift_frac:g}, spread_frac={self.spread_frac:g}): stop once "
                f"every pair's phase difference stayed within {self.spread_frac * self.tol_rad:g} rad of its circular mean for {self.hold_s + self.extra_s:g} s, "
                f"its trend carried to the end moving it by <= {self.drift_frac * self.tol_rad:g} rad, the lateral "
                f"order unchanged and the "
                f"offsets steady by {self.steady.rule}")

    def monitor(self, period_s: float, scale_m: float, end_s: float) -> "_PhaseMonitor":
        """The callable for ``simulate(..., stop=)`` (the run must record ``gait_phase``, ``x``
        and ``y``): ``end_s`` is the full run's duration."""
        return _PhaseMonitor(self, period_s, scale_m, end_s)

    def locked(self, t: np.ndarray, dphi: np.ndarray, time_left_s: float = 0.0) -> bool:
        """The lock part of the rule on samples ``t`` (s) and wrapped pair phase differences
        ``dphi`` (samples, pairs) covering the last ``hold_s + extra_s``, with ``time_left_s``
        to the end of the full run."""
        if len(t) < 2 or t[-1] - t[0] < self.hold_s + self.extra_s - 1e-9:
            return False
        z = np.exp(1j * np.asarray(dphi, float))
        dev = np.angle(z * np.exp(-1j * np.angle(z.mean(axis=0))))  # from the circular mean, per pair
        if (np.abs(dev) > self.spread_frac * self.tol_rad).any():
            return False
        # dev is continuous inside the window (every sample near the mean): its trend is the drift
        slope = np.polyfit(np.asarray(t, float) - t[0], dev, 1)[0]  # rad/s, each pair
        return bool((np.abs(slope) * max(time_left_s, 0.0) <= self.drift_frac * self.tol_rad).all())


class _PhaseMonitor:
    def __init__(self, rule: PhaseStop, period_s: float, scale_m: float, end_s: float):
        self.r, self.end_s = rule, float(end_s)
        self.window_s = rule.hold_s + rule.extra_s
        self.t = np.empty(0)
        self.d = self.o = None
        self.steady = _SteadyMonitor(rule.steady, period_s, scale_m, end_s)
        self.rule = rule.rule

    def __call__(self, blocks: list[dict]) -> str | None:
        steady = self.steady(blocks) is not None
        t = blocks[0]["time"]
        parts = []
        for blk in blocks:
            psi = np.asarray(blk["gait_phase"], float)
            i, j = np.triu_indices(psi.shape[1], 1)
            parts.append(np.angle(np.exp(1j * (psi[:, j] - psi[:, i]))))
        d = np.concatenate(parts, axis=1)
        order = np.concatenate([np.argsort(np.asarray(b["y"]), axis=1, kind="stable") for b in blocks], axis=1)
        self.t = np.concatenate([self.t, t])
        self.d = d if self.d is None else np.concatenate([self.d, d])
        self.o = order if self.o is None else np.concatenate([self.o, order])
        keep = self.t >= self.t[-1] - self.window_s - 1e-9
        first = max(0, int(np.argmax(keep)) - 1)  # one sample before the window: it spans window_s
        self.t, self.d, self.o = self.t[first:], self.d[first:], self.o[first:]
        if not len(self.t) or self.t[-1] < self.r.min_s - 1e-9 or not steady:
            return None
        if not (self.o == self.o[-1]).all() or not self.r.locked(self.t, self.d, self.end_s - self.t[-1]):
            return None
        return f"phase locked and steady by t = {self.t[-1]:g} s"


@dataclass(frozen=True)
class ExcessStop:
    """Stop a packing probe once its mean joint error is decided above or below a level.

    The mean over swimmers, joints and samples after ``skip_s`` is cut into
    batches of ``batch_s``; after at least ``min_batches`` the run stops when
    the batch means' mean lies above (or below) the level by more than
    ``t_{confidence, n-1}`` standard errors (one-sided).  Batch means are
    treated as independent (the pack's error over one half gait period).
    """

    confidence: float = 0.99
    batch_s: float = 1.0
    min_batches: int = 3

    def __post_init__(self):
        from .stats import check_confidence

        check_confidence(self.confidence)
        _positive("batch_s", self.batch_s, "s")
        _count("min_batches", self.min_batches, 1)

    @property
    def rule(self) -> str:
        return (f"ExcessStop(confidence={self.confidence:g}, batch_s={self.batch_s:g}, "
                f"min_batches={self.min_batches}): stop once the mean joint error after the skip is above "
                f"or below the level at one-sided confidence {self.confidence:g} (batch means, Student t)")

    def monitor(self, level_rad: float, skip_s: float) -> "_ExcessMonitor":
        return _ExcessMonitor(self, level_rad, skip_s)

    def side(self, batch_means) -> int:
        """+1 decided above the level (batch means minus it), -1 below, 0 undecided."""
        e = np.asarray(batch_means, float)
        n = len(e)
        if n < max(2, self.min_batches):
            return 0
        half = _special.stdtrit(n - 1, self.confidence) * e.std(ddof=1) / math.sqrt(n)
        return 1 if e.mean() - half > 0 else (-1 if e.mean() + half < 0 else 0)


class _ExcessMonitor:
    def __init__(self, rule: ExcessStop, level_rad: float, skip_s: float):
        self.r, self.level, self.skip = rule, float(level_rad), float(skip_s)
        self.sums: dict[int, float] = {}
        self.counts: dict[int, int] = {}
        self.excess: list[float] = []
        self.rule = f"{rule.rule}; level {self.level:.6g} rad, skip {self.skip:g} s"

    def __call__(self, blocks: list[dict]) -> str | None:
        blk = blocks[0]
        t = blk["time"]
        je = blk["joint_error"].reshape(len(t), -1).mean(axis=1)
        k = np.ceil((t - self.skip) / self.r.batch_s - 1e-9).astype(int) - 1
        for kk in np.unique(k[k >= len(self.excess)]):
            sel = k == kk
            self.sums[kk] = self.sums.get(kk, 0.0) + float(je[sel].sum())
            self.counts[kk] = self.counts.get(kk, 0) + int(sel.sum())
        n_full = int(math.floor((float(t[-1]) - self.skip) / self.r.batch_s + 1e-9)) if len(t) else 0
        while len(self.excess) < n_full:
            kk = len(self.excess)
            self.excess.append(self.sums.pop(kk) / self.counts.pop(kk) - self.level)
        s = self.r.side(self.excess)
        if s:
            return f"{'above' if s > 0 else 'below'} the level after {len(self.excess)} batches"
        return None
