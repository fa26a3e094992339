"""The timeline (``UNDULATE_WARP_TIMELINE``): where a Warp model's time goes, chunk by chunk."""

from __future__ import annotations

import itertools
import json
import os
import threading
import time

from ..execution import current
from ._env import BATCH_LABEL

__all__ = ["Timeline", "TIMELINE_ENV"]

TIMELINE_ENV = "UNDULATE_WARP_TIMELINE"
TIMELINE_FLUSH_S = 1.0  # a model's chunks are written at least this often (wall seconds)

_TIMELINE_IDS = itertools.count()
_TIMELINE_LOCK = threading.Lock()


class Timeline:
    """Where a Warp model's time goes, chunk by chunk (a record for measurements, off unless asked for).

    With ``UNDULATE_WARP_TIMELINE=FILE`` every Warp model (one :class:`undulate.simulation._warp_group._Group`)
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
        self.path = current().timeline
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
