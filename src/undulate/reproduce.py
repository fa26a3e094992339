"""Reproduce the paper: every registered study, three animations, one HTML page, ``claims.json``.

:func:`reproduce` is resumable at two levels: a study whose ``NAME.json``
was written by this code with the same mode and seed
(:func:`undulate.studies.is_current`) is not run again, and inside a study
the sweep engine keeps every finished simulation (``DIR/.sweeps``) and
recomputes any computed by other code or arguments.  Progress
and wall times are kept in ``DIR/reproduce.json`` (written atomically after
every study), so an interrupted reproduction re-run continues where it
stopped.  A study that raises is recorded as failed; the others go on.
An animation is kept only while its code, scene, duration and drawing are
those it was made from (:func:`_animation_stamp`); otherwise it is drawn again.
"""

from __future__ import annotations

import json
import math
import time
import traceback
from pathlib import Path
from typing import Any, Callable

from ._signals import stop_if_signalled
from ._io import atomic_output
from ._source import SourceChangedError
from .errors import ParameterError
from .execution import SIDE_BY_SIDE, Execution, local_workers, runs_ahead, studies_side_by_side, using

__all__ = ["reproduce", "ANIMATIONS"]

_ANIMATIONS_JOB = "(animations)"
_AHEAD = "(ahead) "
"""The job that makes an explaining study's runs ahead of the studies it explains (where it runs wide,
:func:`undulate.execution.runs_ahead`; :func:`undulate.studies.run_ahead`): ``_AHEAD + name``."""

#: The report's animations: (file stem, caption, scene keyword arguments, duration s).
ANIMATIONS = (
    ("compatible_pair", "A compatible pair: dphi = 90 deg started at dx = lambda/4 stays put",
     dict(phases_deg=(0.0, 90.0), dx0_over_lambda=0.25, channel_width_m=0.13), 16.0),
    ("converging_pair", "An incompatible pair: dphi = 90 deg started at dx = 0 is pushed to compatibility",
     dict(phases_deg=(0.0, 90.0), dx0_over_lambda=0.0, channel_width_m=0.13), 24.0),
    ("four_swimmers", "Four swimmers with random phases (d = 0.22 m)",
     dict(phases_deg=(0.0, 137.0, 48.0, 260.0), dx0_over_lambda=0.0, channel_width_m=0.22), 24.0),
)


def _state_path(out: Path) -> Path:
    return out / "reproduce.json"


def _load_state(out: Path, mode: str, seed: int = 0) -> dict:
    p = _state_path(out)
    if p.is_file():
        st = json.loads(p.read_text())
        if st.get("mode") == mode and st.get("seed", 0) == seed:
            return st
    return {"mode": mode, "seed": seed, "studies": {}}


def _save_state(out: Path, state: dict) -> None:
    with atomic_output(_state_path(out)) as tmp:
        tmp.write_text(json.dumps(state, indent=2))


def _study_done(out: Path, name: str, quick: bool, seed: int = 0, execution: Execution | None = None,
                max_looks: int | None = None) -> bool:
    """``NAME.json`` in ``out`` was written by this code, in this mode, with this seed and cap on looks, on
    the engine ``execution`` names (None: the settings in effect)."""
    from .studies import StudyConfig, is_current

    return is_current(name, StudyConfig(out_dir=out, quick=quick, seed=seed, execution=execution,
                                        max_looks=max_looks))


#: How an animation is drawn: its recording rate (Hz), frame stride, frames per second (twice real
#: time) and resolution; part of what :func:`_animation_stamp` records.
ANIMATION_DRAWING = {"sample_rate_hz": 10.0, "stride": 1, "fps": 20, "dpi": 70}


def _animation_stamp(caption: str, kw: dict, duration: float) -> str:
    """What an animation was made from, kept in its ``.nc`` (attribute ``animation_stamp``): the hash of
    the code that simulates and draws it, its scene, duration (s), caption and drawing settings.  An
    animation is drawn again unless the stamp is this one (never reused once its code or parameters
    changed)."""
    from ._source import code_hash

    return json.dumps({"code": code_hash(_make_animation), "scene": kw, "duration_s": float(duration),
                       "caption": caption, **ANIMATION_DRAWING}, sort_keys=True)


def _animation_current(gif: Path, nc: Path, stamp: str) -> bool:
    """``gif`` exists and ``nc`` records ``stamp`` (an unreadable ``nc`` is not current)."""
    import xarray as xr

    if not (gif.is_file() and nc.is_file()):
        return False
    try:
        with xr.open_dataset(nc) as ds:
            return ds.attrs.get("animation_stamp") == stamp
    except (OSError, ValueError):
        return False


def _make_animation(out: Path, stem: str, caption: str, kw: dict, duration: float) -> dict:
    from .animation import animate
    from .params import Channel, Scene, SimOptions
    from .simulation import simulate
    from ._io import write_netcdf

    anim_dir = out / "animations"
    anim_dir.mkdir(exist_ok=True)
    gif, nc = anim_dir / f"{stem}.gif", anim_dir / f"{stem}.nc"
    stamp = _animation_stamp(caption, kw, duration)
    if not _animation_current(gif, nc, stamp):
        sc = Scene(phases_rad=tuple(math.radians(p) for p in kw["phases_deg"]),
                   channel=Channel(width_m=kw["channel_width_m"]))
        sc = Scene(phases_rad=sc.phases_rad, channel=sc.channel, dx0_m=kw["dx0_over_lambda"] * sc.wavelength_m)
        # an illustration, one scene: stepped by MuJoCo on the CPU whatever the session's backend
        # (one world is the GPU's slowest case, and each worker process would compile its kernels)
        d = ANIMATION_DRAWING
        ds = simulate(sc, SimOptions(duration_s=duration, sample_rate_hz=d["sample_rate_hz"], backend="mujoco"))
        ds.attrs["animation_stamp"] = stamp
        gif.unlink(missing_ok=True)  # the stamp below is the gif's: a gif drawn from another stays out
        write_netcdf(ds, nc)
        animate(ds, gif, stride=d["stride"], fps=d["fps"], dpi=d["dpi"], title=caption)
    return _animation_entry(stem, caption)


def _animation_entry(stem: str, caption: str) -> dict:
    """The report's entry for animation ``stem``: its GIF and data, relative to the output folder."""
    return {"file": f"animations/{stem}.gif", "data": f"animations/{stem}.nc", "caption": caption}


def _animations(out: Path, animation_s: float | None, log: Callable[[str], None], workers: int | None) -> list[dict]:
    """The report's animations, drawn side by side on the local worker processes (the warm
    pool; ``workers == 1``: here, one after the other).  An animation that fails, or whose
    process dies, is drawn here instead; one that fails here too is logged and left out."""
    from concurrent.futures.process import BrokenProcessPool

    from .sweep import local_pool

    jobs = [(stem, caption, kw, dur if animation_s is None else animation_s) for stem, caption, kw, dur in ANIMATIONS]
    done: dict[str, dict] = {}
    anim_dir = out / "animations"
    for stem, caption, kw, dur in jobs:  # current ones are kept here, without starting a worker for them
        if _animation_current(anim_dir / f"{stem}.gif", anim_dir / f"{stem}.nc", _animation_stamp(caption, kw, dur)):
            done[stem] = _animation_entry(stem, caption)
    todo = [j for j in jobs if j[0] not in done]
    n = min(workers or local_workers(), len(todo))
    if n > 1:
        try:
            with local_pool(n) as pool:
                futs = {stem: pool.submit(_make_animation, out, stem, caption, kw, dur)
                        for stem, caption, kw, dur in todo}
                for stem, fut in futs.items():
                    try:
                        done[stem] = fut.result()
                    except Exception:  # noqa: BLE001 - incl. BrokenProcessPool: retried here below
                        pass
        except BrokenProcessPool:  # pragma: no cover - retried here below
            pass
    anims = []
    for stem, caption, kw, dur in jobs:
        if stem not in done:
            try:
                done[stem] = _make_animation(out, stem, caption, kw, dur)
            except Exception as e:  # pragma: no cover - reported in the log and on the page
                stop_if_signalled()
                log(f"animation {stem}: FAILED: {type(e).__name__}: {e}")
                continue
        anims.append(done[stem])
    return anims


def reproduce(out_dir: str | Path, *, quick: bool = True, scheduler: str | None = None, seed: int = 0,
              studies: list[str] | None = None, log: Callable[[str], None] = print,
              animation_s: float | None = None, workers: int | None = None,
              side_by_side: int | None = None, beyond_paper: bool = False,
              execution: Execution | None = None, max_looks: int | None = None) -> tuple[Path, list[dict]]:
    """Run every registered study (or ``studies``) and write ``out_dir/index.html``.

    ``beyond_paper``: also run the studies beyond the reproduced paper (``Study.reference`` not
    ``"paper"``: the PRX 2021 synchronization comparisons, which judge our candidate controllers against
    another paper).  Not by default, in either mode (a reproduction is the paper's claims, and full mode's
    15-minute budget on 2 cores is theirs; the page says what was left out).
    Ignored when ``studies`` names the studies.

    ``animation_s`` overrides the simulated duration of each animation (s, at least
    :data:`MIN_ANIMATION_S`); an animation still current (same code, scene, duration and drawing) is kept.
    ``workers``: local worker processes (default: every core this process may
    use); one pool of them stays warm across every study's sweeps.
    ``execution``: how every run is executed (:class:`undulate.execution.Execution`, which then holds
    the workers and scheduler; default: the settings in effect with ``workers`` and ``scheduler``).
    ``side_by_side``: studies run at once (threads sharing that pool; an explaining study waits for
    the studies it explains).  Default (:func:`undulate.execution.studies_side_by_side`):
    :data:`~undulate.execution.SIDE_BY_SIDE` on a few cores, where the reproduction's
    time is its work; every study at once, with explaining studies' runs made ahead, where it runs
    wide (:data:`undulate.execution.WIDE_WORKERS` or more local workers, where its time is
    its chain of sequential stages; or the Warp backend, each Warp model on its own stream of the
    device, so that their small batches overlap there: a step costs a GPU about the same at any small
    number of worlds, docs/gpu.md).  Results do not depend on it: every run's result is a function of
    its parameters and seed, and each study judges its own runs.

    ``max_looks``: every study stops after at most this many looks (None: every look while a claim is
    undecided).  A budget in runs: fewer looks take fewer runs and leave more verdicts undecided, each
    judged at the level of a plan of that many looks (:attr:`undulate.studies.StudyConfig.max_looks`);
    the page's mode says so.

    Returns the report path and the per-study statuses (``name``, ``ok``,
    ``wall_s``, ``error``, ``reused``).  Another process writing to ``out_dir`` (a reproduction or a
    study) is a :class:`~undulate.errors.ParameterError` before anything is written
    (:func:`undulate._outdir.writing_to`).
    """
    from . import studies as registry
    from ._outdir import writing_to
    from .studies import StudyConfig
    from .sweep import warm_workers

    cfg = StudyConfig(out_dir=out_dir, quick=quick, scheduler=scheduler, seed=seed, workers=workers,
                      execution=execution, max_looks=max_looks)  # validated first
    ex = cfg.execution
    check_animation_s(animation_s)
    log = _one_line_at_a_time(log)
    if studies is None:
        beyond = bool(beyond_paper)
        studies = [n for n in registry.names() if beyond or registry.describe(n).reference == "paper"]
    if side_by_side is None:
        side_by_side = studies_side_by_side(len(studies), ex)  # every study at once: + the animations
    with writing_to(out_dir, "out_dir"), warm_workers(ex.workers), using(ex):
        return _reproduce(registry, Path(out_dir), quick, ex, seed, studies, log, animation_s, side_by_side,
                          cfg.max_looks)


#: The shortest animation (s): two frames at the drawing's recording rate.
MIN_ANIMATION_S = 2.0 / ANIMATION_DRAWING["sample_rate_hz"]
#: The longest animation (s): a GIF's frames are held in memory until it is written, ~0.3 MB each at
#: the drawing's resolution, so 600 s at its 10 frames a simulated second is ~2 GB an animation.
MAX_ANIMATION_S = 600.0


def check_animation_s(animation_s: float | None, name: str = "animation_s") -> None:
    """``animation_s`` is None (each animation's own duration) or a number of seconds in
    [:data:`MIN_ANIMATION_S`, :data:`MAX_ANIMATION_S`]; else a :class:`~undulate.errors.ParameterError`
    naming it (as ``name``)."""
    if animation_s is None:
        return
    import numbers

    ok = (isinstance(animation_s, numbers.Real) and not isinstance(animation_s, bool)
          and math.isfinite(animation_s) and MIN_ANIMATION_S <= animation_s <= MAX_ANIMATION_S)
    if not ok:
        raise ParameterError(name, f"seconds in [{MIN_ANIMATION_S:g}, {MAX_ANIMATION_S:g}] (two frames; a GIF's "
                             "frames are held in memory until it is written)", animation_s)


def _one_line_at_a_time(log: Callable[[str], None]) -> Callable[[str], None]:
    """``log`` behind a lock: studies side by side log from two threads, and ``print`` writes a line
    and its newline apart."""
    import threading

    lock = threading.Lock()

    def logged(message: str) -> None:
        with lock:
            log(message)
    return logged


def _run_ahead(registry, name: str, label: str, log: Callable[[str], None], out: Path, **config) -> None:
    """The job that makes explaining study ``name``'s runs ahead (:func:`undulate.studies.run_ahead`),
    logged under ``label``.  If it fails, the study itself computes what is missing, and reports."""
    try:
        got = registry.run_ahead(name, out, **config)
        log(f"{label}: {got['n_computed']} of its runs made ahead in {got['wall_s']:.1f} s")
    except (KeyboardInterrupt, SourceChangedError):
        raise
    except Exception as e:  # noqa: BLE001
        log(f"{label}: its runs ahead stopped ({type(e).__name__}: {e}); the study makes them")


def _dependencies(registry, names: list[str]) -> dict[str, set[str]]:
    """``name -> the studies among names it must wait for``: those whose claims it explains (an
    explaining study reads their verdicts, :meth:`undulate.studies.StudyContext.needs_explanation`)."""
    return {n: {e.study for e in registry.describe(n).explanations} & set(names) - {n} for n in names}


def _side_by_side(todo: list[str], deps: dict[str, set[str]], one: Callable[[str], Any],
                  finished: Callable[[str, Any], None], at_once: int) -> None:
    """Run ``one(name)`` for every name of ``todo``, at most ``at_once`` at a time on threads, each
    only once the jobs it depends on (``deps``, among ``todo``) have finished; ``finished(name,
    result)`` is called here, in this thread, as each ends.  Among the jobs ready to start, those that
    waited for others go first (an explaining study: the longest), then those others wait for (so that
    it starts early), then the rest, each kind in ``todo``'s order.  Threads start in a copy of this
    context (a physics meter open here sees what they simulate).  An interrupt (Ctrl-C, a changed
    source) stops the sweeps in flight (:func:`undulate.sweep.stop_sweeps`) and is raised
    once their threads end."""
    import contextvars
    from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait

    from .sweep import stop_sweeps

    if at_once == 1:
        for name in todo:
            finished(name, one(name))
        return
    waiting, running, done = list(todo), {}, set()
    feeds = set().union(*deps.values()) if deps else set()
    with ThreadPoolExecutor(max_workers=at_once, thread_name_prefix="undulate-study") as threads:
        try:
            while waiting or running:
                ready = [n for n in waiting if not (deps.get(n, set()) & (set(todo) - done))]
                if not ready and not running:  # a cycle among the dependencies: take them in order
                    ready = waiting[:1]
                ready.sort(key=lambda n: 0 if deps.get(n) else 1 if n in feeds else 2)  # stable within each
                for name in ready[: at_once - len(running)]:
                    waiting.remove(name)
                    running[threads.submit(contextvars.copy_context().run, one, name)] = name
                finished_now, _ = wait(running, return_when=FIRST_COMPLETED)
                for fut in finished_now:
                    name = running.pop(fut)
                    done.add(name)
                    finished(name, fut.result())
        except BaseException:
            stop_sweeps()
            for fut in running:
                fut.cancel()
            wait(running)
            raise


def _reproduce(registry, out: Path, quick: bool, ex: Execution, seed: int, studies, log, animation_s,
               side_by_side: int = SIDE_BY_SIDE, max_looks: int | None = None) -> tuple[Path, list[dict]]:
    from .report import write_report

    out.mkdir(parents=True, exist_ok=True)
    mode = ("quick" if quick else "full") + ("" if max_looks is None else
                                              f", at most {max_looks} look{'s' if max_looks > 1 else ''} a study")
    names = list(studies) if studies is not None else registry.names()
    for n in names:
        registry.describe(n)  # unknown names fail before any work
    state = _load_state(out, mode, seed)
    t_all = time.perf_counter()
    results: dict[str, dict] = {}
    todo: list[str] = []
    for i, name in enumerate(names, 1):
        prev = state["studies"].get(name, {})
        if _study_done(out, name, quick, seed, ex, max_looks):
            log(f"[{i}/{len(names)}] {name}: done earlier ({prev.get('wall_s', float('nan')):.1f} s), kept")
            results[name] = {"name": name, "ok": True, "wall_s": prev.get("wall_s"), "error": None, "reused": True}
        else:
            todo.append(name)
    number = {n: i for i, n in enumerate(names, 1)}

    def one(name: str) -> dict:
        stop_if_signalled()  # terminated while the last study wrote its figures: none more starts
        log(f"[{number[name]}/{len(names)}] {name}: running ({mode})")
        t0 = time.perf_counter()
        try:
            registry.run_study(name, out, quick=quick, seed=seed, execution=ex, max_looks=max_looks)
            st = {"name": name, "ok": True, "wall_s": time.perf_counter() - t0, "error": None, "reused": False}
            log(f"[{number[name]}/{len(names)}] {name}: done in {st['wall_s']:.1f} s")
        except (KeyboardInterrupt, SourceChangedError):  # the code changed under us: nothing after is attributable
            raise
        except Exception as e:  # a failed study is reported, the others go on
            stop_if_signalled()  # not when the error is a SIGTERM that C code reported as its own
            st = {"name": name, "ok": False, "wall_s": time.perf_counter() - t0,
                  "error": f"{type(e).__name__}: {e}", "reused": False,
                  "traceback": traceback.format_exc()}
            log(f"[{number[name]}/{len(names)}] {name}: FAILED: {st['error']}")
        return st

    anims: list[dict] = []
    deps = _dependencies(registry, names)
    ahead = [n for n in todo if deps.get(n, set()) & set(todo)] if runs_ahead(ex) else []

    def job(name: str) -> Any:
        if name == _ANIMATIONS_JOB:
            return _animations(out, animation_s, log, ex.workers)
        if name.startswith(_AHEAD):
            name = name[len(_AHEAD):]
            return _run_ahead(registry, name, f"[{number[name]}/{len(names)}] {name}", log,
                              out, quick=quick, seed=seed, execution=ex, max_looks=max_looks)
        return one(name)

    def finished(name: str, result: Any) -> None:
        if name == _ANIMATIONS_JOB:
            anims.extend(result)
            return
        if name.startswith(_AHEAD):  # no study of its own: what it made, the study reads
            return
        results[name] = result
        state["studies"][name] = {k: v for k, v in result.items() if k != "reused"}
        _save_state(out, state)

    # the animations are one more job, beside the last studies (they use the same worker pool)
    # (the runs ahead first among the jobs nothing waits for: they start beside the studies they wait for)
    _side_by_side([_AHEAD + n for n in ahead] + todo + [_ANIMATIONS_JOB], deps, job, finished,
                  max(1, int(side_by_side)) + len(ahead))
    statuses = [results[n] for n in names]
    from .claims import collect, write_claims_json

    write_claims_json(out, collect(out, [s["name"] for s in statuses if s.get("ok")]))
    total = time.perf_counter() - t_all
    # wall time spent on this folder's reproduction: this run's and that of earlier runs it resumes
    state["wall_s"] = float(state.get("wall_s", 0.0)) + total if todo else state.get("wall_s")
    _save_state(out, state)
    path = write_report(out, statuses, mode=mode, animations=anims, total_wall_s=state.get("wall_s"))
    log(f"wrote {path} ({total:.0f} s this run)")
    return path, statuses
