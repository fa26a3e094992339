"""Progress of a sweep: a tqdm bar on a terminal, plain lines otherwise."""

from __future__ import annotations

import sys
import time
from typing import TextIO


def _hms(seconds: float) -> str:
    s = int(round(seconds))
    h, s = divmod(s, 3600)
    m, s = divmod(s, 60)
    return f"{h}h{m:02d}m{s:02d}s" if h else (f"{m}m{s:02d}s" if m else f"{s}s")


EVERY_S = 10.0
"""Seconds between plain progress lines (not on a terminal)."""


class Progress:
    """Counts finished runs out of ``total`` (``initial`` of them already done).

    On a terminal: a tqdm bar with rate and ETA.  Otherwise (CI logs, batch
    jobs): one line every ``every_s`` seconds (:data:`EVERY_S`) or every 10 % of the runs to
    compute, whichever comes first.  ``enabled=False`` prints nothing.
    """

    def __init__(self, total: int, initial: int, *, enabled: bool = True, stream: TextIO | None = None,
                 every_s: float | None = None, label: str = "sweep"):
        self.total = total
        self.initial = initial
        self.done = initial
        self.failed = 0
        self.enabled = enabled
        self.stream = stream if stream is not None else sys.stderr
        self.every_s = EVERY_S if every_s is None else every_s
        self.label = label
        self._t0 = time.monotonic()
        self._last_t = self._t0
        self._last_decile = 0
        self._bar = None
        if not enabled:
            return
        isatty = getattr(self.stream, "isatty", None)
        if isatty is not None and isatty():
            from tqdm.auto import tqdm

            self._bar = tqdm(total=total, initial=initial, desc=label, unit="run", file=self.stream,
                             dynamic_ncols=True, smoothing=0.05)

    def write(self, line: str) -> None:
        """A message that does not break the bar."""
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.write(line, file=self.stream)
        else:
            print(line, file=self.stream, flush=True)

    def update(self, n_ok: int, n_failed: int = 0) -> None:
        n = n_ok + n_failed
        self.done += n
        self.failed += n_failed
        if not self.enabled:
            return
        if self._bar is not None:
            self._bar.update(n)
            if n_failed:
                self._bar.set_postfix(failed=self.failed, refresh=False)
            return
        now = time.monotonic()
        todo = max(self.total - self.initial, 1)
        decile = int(10 * (self.done - self.initial) / todo)
        if now - self._last_t >= self.every_s or decile > self._last_decile or self.done == self.total:
            self._last_t = now
            self._last_decile = decile
            self.write(self._line(now))

    def stepping(self, done: float, total: float, worlds: int) -> None:
        """Progress inside a batch whose runs step together (a Warp sweep's worlds, which all finish
        at its end): ``done`` of ``total`` simulated world-seconds, ``worlds`` worlds.  Shown beside
        the bar on a terminal, else as a line every ``every_s`` seconds (called from the stepping
        thread, after each chunk)."""
        if not self.enabled or total <= 0:
            return
        now = time.monotonic()
        frac = min(max(done / total, 0.0), 1.0)
        if self._bar is not None:
            self._bar.set_postfix_str(f"stepping {worlds} worlds together: {100 * frac:.0f}%")
            return
        if frac < 1.0 and now - self._last_t < self.every_s:
            return
        self._last_t = now
        elapsed = now - self._t0
        eta = _hms(elapsed * (1 - frac) / frac) if frac > 0 else "?"
        self.write(f"{self.label}: stepping {worlds} worlds together, {100 * frac:.0f}% of their simulated time, "
                   f"elapsed {_hms(elapsed)}, ETA {eta}")

    def _line(self, now: float) -> str:
        elapsed = now - self._t0
        computed = self.done - self.initial
        rate = computed / elapsed if elapsed > 0 else 0.0
        left = self.total - self.done
        eta = _hms(left / rate) if rate > 0 else "?"
        pct = 100.0 * self.done / self.total if self.total else 100.0
        fail = f", {self.failed} failed" if self.failed else ""
        return (f"{self.label}: {self.done}/{self.total} runs ({pct:.0f}%){fail}, "
                f"{rate:.2f} runs/s, elapsed {_hms(elapsed)}, ETA {eta}")

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None
