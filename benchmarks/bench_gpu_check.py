"""The GPU check (issue 37): one prepared run on a GPU machine, every figure in one go.

    python benchmarks/bench_gpu_check.py OUTDIR [--budget-s 540] [--only STEPS] [--cpu-verdicts FILE]

Run by ``benchmarks/gpu_check.sh`` (which installs the carried wheels first).  Prints one JSON line
per measurement as it goes and keeps ``OUTDIR/gpu_check.json`` up to date, so a run cut short still
leaves what it measured.  Steps, in the order ``--only`` gives (default: all, in the order of
:data:`STEPS`: pair, full-warp, quick-warp-warm, quick-cpu, quick-warp, pair-throughput, pack,
pack-throughput, determinism, sweep, side-by-side):

* ``pair`` -- the default pair over 5 s, Warp on the device against the MuJoCo backend (float64, CPU)
  on the same machine: max |dx|, penetration.  The first Warp call compiles the kernels: its time is
  reported apart (``compile_s``).
* ``quick-warp``, ``full-warp`` -- ``undulate reproduce --quick`` / ``--full`` with ``--backend warp``,
  each in a fresh folder: wall time, the Warp models' first steps (kernel compilation unless cached,
  reported apart), where the models' time went (``warp_timeline``: models stepping at once, a step's
  time against that number, the host's share; ``benchmarks/bench_warp_timeline.py``), per-study times and
  the verdicts, compared claim by claim with the MuJoCo
  backend's (``--cpu-verdicts``: made elsewhere from the same commit by
  ``benchmarks/bench_gpu_check_reference.py``; or step ``quick-cpu``'s, quick on the MuJoCo backend
  here, with every core).
* ``quick-warp-warm`` -- quick in a fresh folder after a Warp reproduction (full, or a cold quick) has
  compiled the kernels: its wall time is the stepping's (any first steps still compiling are
  reported apart, as above).
* ``quick-cpu`` -- quick on the MuJoCo backend on this machine's cores: the baseline of the Warp
  runs' times in the same run, and their verdicts' reference where ``--cpu-verdicts`` gives none
  (with it, the two MuJoCo reproductions' verdicts must be equal, and are compared).
* ``pair-throughput``, ``pack-throughput`` -- world-steps per second against the number of worlds,
  for the pair (1 / 1 024 / 8 192 / 32 768 worlds) and a jammed 50-swimmer pack (1 / 64 / 512): on the
  device alone (the CUDA graph of one step, launched per step) and end to end (controls up, every
  step's state and sensors down, as :func:`undulate.simulation.simulate_batch` pays it).
* ``pack`` -- the pack over 2 s against the MuJoCo backend: penetration (the 1 mm rule).
* ``determinism`` -- MuJoCo Warp's determinism on and off (off is the default on a GPU): four
  identical worlds of the pack over 1 s (their largest difference), and the pair's device-only
  throughput at 8 192 worlds.  On an H200 (2026-11-27) the deterministic pack could not allocate its
  workspace: the step reports that error and goes on.

* ``sweep`` -- a user's sweep end to end: 1 024 pair runs of 5 s through ``run_sweep`` on Warp in one
  process, on Warp split over 8 processes (``UNDULATE_WARP_PROCESSES``) and on the MuJoCo backend on
  every core: runs per second (:func:`sweep`; on 2 cores a run's host work besides its steps was
  ~18 ms, 2026-11-27, docs/gpu.md "The host's share of a sweep").
* ``side-by-side`` -- whether small Warp models stepping at once overlap on the device, as a
  reproduction's studies step theirs (:func:`side_by_side`; on the H200 on 2026-11-27 ~20 of them
  made each step ~8x slower than one model's alone).

Every step has a time limit taken from ``--budget-s`` so the whole check ends in time.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

T0 = time.perf_counter()
RESULTS: dict = {}
OUT: Path = Path(".")
DEVICE = "cuda"
STUDIES = ""  # --studies: reproduce these only (comma-separated)
CPU_VERDICTS: str | None = None  # --cpu-verdicts
REF: dict = {}  # mode -> the MuJoCo backend's reproduction (its verdicts)
WARP: dict = {}  # step -> a Warp reproduction of this run (compared with quick-cpu once it has run)
SPS = 10  # steps per sample interval in the reduced throughput (a pair sampled at 10 Hz has 150)
SMALL = False  # --dry-run: tiny sizes, to check the script itself on Warp's CPU device


def say(key: str, value) -> None:
    RESULTS[key] = value
    print(json.dumps({key: value, "t_s": round(time.perf_counter() - T0, 1)}), flush=True)
    (OUT / "gpu_check.json").write_text(json.dumps(RESULTS, indent=1, default=str))


def left(budget: float) -> float:
    return budget - (time.perf_counter() - T0)


CORES_UP_TO_ENV = "UNDULATE_WARP_CORES_UP_TO"  # undulate.execution.cores_up_to
FALLBACKS = {"UNDULATE_WARP_STREAMS": "0", "UNDULATE_WARP_COMPILE_WORKERS": "1", "UNDULATE_WARP_STEPS_PER_GRAPH": "1",
             "UNDULATE_WARP_DETERMINISTIC": "0"}
"""Settings the check turns to the plain way, one more at a time, while the pair's first run fails
(each: a path of the Warp backend first run on a GPU here): one stream, kernels compiled by the first
step, one step per graph, MuJoCo Warp's determinism off; every later step inherits them."""


def agreement(which: str) -> None:
    """``pair``: the default pair over 5 s; ``pack``: a jammed 50-swimmer pack over 2 s; Warp against
    the MuJoCo backend.  If the pair's first run fails, the check turns the :data:`FALLBACKS` to the
    plain way one at a time until it runs, and says which."""
    import numpy as np

    from undulate import Scene, SimOptions, simulate
    from undulate.simulation._warp import device_name
    from undulate.studies.packing import _pack

    if which == "pair":
        say("device", device_name(DEVICE))
        # modules benchmarks/bench_gpu_kernels.py compiled ahead of time, copied by gpu_check.sh into Warp's
        # kernel cache (0: none): with them, pair.compile_s shows whether the device found them
        say("precompiled_kernel_modules", int(os.environ.get("UNDULATE_PRECOMPILED_KERNELS", "0")))
        sc = Scene(phases_rad=(0.0, math.pi / 2))
        for fallback in (*FALLBACKS, None):
            t = time.perf_counter()
            try:
                simulate(sc, SimOptions(duration_s=0.05, backend="warp", device=DEVICE))
                break
            except Exception as e:  # noqa: BLE001 - a path never run on this device failed: fall back, say so
                if fallback is None:
                    raise
                say(f"pair.error_before_{fallback}", f"{type(e).__name__}: {e}"[:800])
                os.environ[fallback] = FALLBACKS[fallback]
        say("pair.compile_s", time.perf_counter() - t)
        say("settings", {k: os.environ.get(k, "default") for k in FALLBACKS})
        t = time.perf_counter()
        pair_s = 0.2 if SMALL else 5.0
        a = simulate(sc, SimOptions(duration_s=pair_s))
        cpu_s = time.perf_counter() - t
        t = time.perf_counter()
        b = simulate(sc, SimOptions(duration_s=pair_s, backend="warp", device=DEVICE))
        say("pair.agreement_5s", {"max_dx_m": float(np.abs(a["x"].values - b["x"].values).max()),
                                  "max_dy_m": float(np.abs(a["y"].values - b["y"].values).max()),
                                  "penetration_max_m": float(b["penetration"].max()),
                                  "cpu_s": cpu_s, "warp_s": time.perf_counter() - t})
        return
    pack = _pack({"phi_max_rad": math.pi, "rho_tilde": 3.0, "draw": 0}, amplitude_m=0.05226, base_seed=0,
                 n_swimmers=50)[0]
    opts = dict(duration_s=0.2 if SMALL else 2.0, sample_rate_hz=10.0, record=("x", "y", "penetration"))
    t = time.perf_counter()
    simulate(pack, SimOptions(**{**opts, "duration_s": 0.1}, backend="warp", device=DEVICE))
    say("pack.compile_s", time.perf_counter() - t)
    t = time.perf_counter()
    a = simulate(pack, SimOptions(**opts))
    cpu_s = time.perf_counter() - t
    t = time.perf_counter()
    b = simulate(pack, SimOptions(**opts, backend="warp", device=DEVICE))
    say("pack.agreement_2s", {"max_dx_m": float(np.abs(a["x"].values - b["x"].values).max()),
                              "penetration_max_m": float(b["penetration"].max()),
                              "penetration_max_cpu_m": float(a["penetration"].max()),
                              "cpu_s": cpu_s, "warp_s": time.perf_counter() - t})


def throughput(which: str, budget: float) -> None:
    import numpy as np

    from undulate import Scene, SimOptions
    from undulate.simulation._warp import WarpRollout, _Reduction
    from undulate.simulation._warp_group import _device_seconds
    from undulate.simulation import _initial_state, compile_scene, resolve_options
    from undulate.studies.packing import _pack

    pack = _pack({"phi_max_rad": math.pi, "rho_tilde": 3.0, "draw": 0}, amplitude_m=0.05226, base_seed=0,
                 n_swimmers=50)[0]
    cases = [("pair", Scene(phases_rad=(0.0, math.pi / 2)), (1, 1024, 8192, 32768), 200),
             ("pack", pack, (1, 64, 512), 100)]  # one world: the step's floor, what a lone run pays
    if SMALL:
        cases = [(n, sc, (2, 4), 10) for n, sc, _, _ in cases]
    cases = [c for c in cases if c[0] == which]
    for name, sc, worlds, k in cases:
        opts = resolve_options(sc, SimOptions(duration_s=1.0, backend="warp", device=DEVICE,
                                              record=("x", "y", "penetration") if name == "pack" else None))
        cs = compile_scene(sc, opts)
        s0, _ = _initial_state(cs.model)
        u1 = cs.controls(np.arange(k) * opts.timestep_s)
        for nw in worlds:
            if left(budget) < 30:
                say(f"{name}.worlds_{nw}", "skipped: budget")
                continue
            try:
                r = WarpRollout([cs] * nw, opts, DEVICE)
                cur = np.tile(s0, (nw, 1))
                u = np.broadcast_to(u1, (nw, k, u1.shape[1]))
                st = np.empty((nw, k, s0.size))
                sd = np.empty((nw, k, cs.model.nsensordata))
                r.rollout(cur, u, st, sd, k)  # graph capture
                t = time.perf_counter()
                r.rollout(cur, u, st, sd, k)
                e2e = time.perf_counter() - t
                dev = _device_seconds(r.groups[0], k)
                r.close()
                # reduced on the device (open-loop runs since 2026-11-26): one sample row in sps steps
                ix = cs.index
                red = _Reduction(SPS, ix.sens_pair, ix.sens_wall, ix.sens_mindist,
                                 [sc.contact.max_penetration_m] * nw)
                r = WarpRollout([cs] * nw, opts, DEVICE, reduce=red)
                r.rollout_samples(cur, u, k)  # graph capture
                t = time.perf_counter()
                r.rollout_samples(cur, u, k)
                e2e_red = time.perf_counter() - t
                say(f"{name}.worlds_{nw}", {"steps": k, "device_world_steps_per_s": nw * k / dev,
                                            "end_to_end_world_steps_per_s": nw * k / e2e,
                                            "end_to_end_reduced_world_steps_per_s": nw * k / e2e_red,
                                            "steps_per_sample": SPS, "device_s_per_step": dev / k})
                r.close()
                del st, sd
            except Exception as e:  # noqa: BLE001 - report and go on
                say(f"{name}.worlds_{nw}", f"error: {type(e).__name__}: {e}"[:500])


def determinism(budget: float) -> None:
    """MuJoCo Warp's determinism (``undulate.simulation._warp.determinism``; on by default), on and
    off: four identical worlds of the jammed pack over 1 s (the largest difference between their
    centres: 0 when deterministic; GPU.md measured 4 cm after 1 s without), and what it costs the pair
    on the device alone at 8 192 worlds."""
    import numpy as np

    from undulate import Scene, SimOptions
    from undulate.simulation import _initial_state, compile_scene, resolve_options, simulate_batch
    from undulate.simulation._warp import WarpRollout
    from undulate.simulation._warp_group import _device_seconds
    from undulate.studies.packing import _pack

    pack = _pack({"phi_max_rad": math.pi, "rho_tilde": 3.0, "draw": 0}, amplitude_m=0.05226, base_seed=0,
                 n_swimmers=50)[0]
    pair = Scene(phases_rad=(0.0, math.pi / 2))
    nw, k = (4, 10) if SMALL else (8192, 200)
    saved = os.environ.get("UNDULATE_WARP_DETERMINISTIC")
    try:
        for flag in ("1", "0"):
            if left(budget) < 40:
                say(f"determinism.{flag}", "skipped: budget")
                continue
            os.environ["UNDULATE_WARP_DETERMINISTIC"] = flag
            fig: dict = {}
            try:  # each part on its own: an error (the deterministic pack's workspace on an H200) is said
                t = time.perf_counter()
                runs = simulate_batch([pack] * 4, SimOptions(duration_s=0.1 if SMALL else 1.0, sample_rate_hz=10.0,
                                                             record=("x", "y", "penetration"), backend="warp",
                                                             device=DEVICE))
                fig.update(pack_identical_worlds_max_dxy_m=max(
                    float(np.abs(r[v].values - runs[0][v].values).max()) for r in runs[1:] for v in ("x", "y")),
                    pack_1s_wall_s=time.perf_counter() - t)
            except Exception as e:  # noqa: BLE001
                fig["pack_error"] = f"{type(e).__name__}: {e}"[:500]
            try:
                opts = resolve_options(pair, SimOptions(duration_s=1.0, backend="warp", device=DEVICE))
                cs = compile_scene(pair, opts)
                s0, _ = _initial_state(cs.model)
                u = np.broadcast_to(cs.controls(np.arange(k) * opts.timestep_s), (nw, k, cs.model.nu))
                r = WarpRollout([cs] * nw, opts, DEVICE)
                st, sd = np.empty((nw, k, s0.size)), np.empty((nw, k, cs.model.nsensordata))
                r.rollout(np.tile(s0, (nw, 1)), u, st, sd, k)  # compilation, graph capture
                dev = _device_seconds(r.groups[0], k)
                r.close()
                fig.update(pair_worlds=nw, pair_device_world_steps_per_s=nw * k / dev)
            except Exception as e:  # noqa: BLE001
                fig["pair_error"] = f"{type(e).__name__}: {e}"[:500]
            say(f"determinism.{flag}", fig)
    finally:
        if saved is None:
            os.environ.pop("UNDULATE_WARP_DETERMINISTIC", None)
        else:
            os.environ["UNDULATE_WARP_DETERMINISTIC"] = saved


SWEEP_PROCESSES = 8  # UNDULATE_WARP_PROCESSES of the sweep step's second Warp sweep


def sweep(budget: float) -> None:
    """A user's sweep end to end (``benchmarks/bench_sweep_host.py``): 1 024 pair runs of 5 s through
    ``run_sweep`` into a fresh store, on the Warp backend in one process (the runs' host work --
    models, control tables, Datasets, run files -- on one core), on Warp split over
    :data:`SWEEP_PROCESSES` processes (``UNDULATE_WARP_PROCESSES``: the host work on as many cores, the
    processes' batches sharing the device), and on the MuJoCo backend on every core.  Each after a
    warm-up sweep (processes started, kernels loaded); runs per second, best of two."""
    script = Path(__file__).resolve().parent / "bench_sweep_host.py"
    runs, dur = (8, 0.2) if SMALL else (1024, 5.0)
    cases = (("warp_1_process", ["--backend", "warp", "--device", DEVICE]),
             (f"warp_{SWEEP_PROCESSES}_processes", ["--backend", "warp", "--device", DEVICE,
                                                    "--processes", str(2 if SMALL else SWEEP_PROCESSES)]),
             ("mujoco_every_core", ["--backend", "mujoco", "--workers", str(os.cpu_count() or 1)]))
    for name, args in cases:
        if left(budget) < 40:
            say(f"sweep.{name}", "skipped: budget")
            continue
        cmd = [sys.executable, str(script), "--runs", str(runs), "--duration", str(dur), "--repeat", "2", *args]
        say(f"sweep.{name}", _json_line(cmd, max(20.0, left(budget) - 20.0)))


def _run_group(cmd: list[str], timeout: float, env: dict | None = None) -> tuple[int | str, str, str]:
    """``cmd`` in a session of its own: ``(return code, stdout, stderr)``, or ``("timeout", ...)`` with what
    it printed, after killing its whole process group: ``subprocess.run``'s timeout kills the command
    only, and a reproduction's worker processes would go on competing for the cores with the next step
    (the lease of 2026-11-29 measured ``quick-cpu`` right after a ``quick-warp`` cut at its limit)."""
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                         start_new_session=True)
    try:
        out, err = p.communicate(timeout=timeout)
        return p.returncode, out, err
    except subprocess.TimeoutExpired:
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        out, err = p.communicate()
        return "timeout", out or "", err or ""


def _json_line(cmd: list[str], timeout: float, env: dict | None = None):
    """What a benchmark script run as ``cmd`` printed on its last ``json ...`` line; else its error
    (return code and output's end), or ``"timeout"``."""
    rc, out, err = _run_group(cmd, timeout, env)
    if rc == "timeout":
        return "timeout"
    found = [x for x in out.splitlines() if x.startswith("json ")]
    return json.loads(found[-1][5:]) if found else f"error: rc {rc}: {(out + err)[-800:]}"


def side_by_side(budget: float) -> None:
    """Do small Warp models stepping side by side overlap on the device
    (``benchmarks/bench_warp_side_by_side.py``): 1-16 pair models of 18 worlds each on their own
    threads and streams, their steps' wall time on the device alone and end to end, against one model
    holding all their worlds; once with the CUDA driver's default hardware queues and once with
    ``CUDA_DEVICE_MAX_CONNECTIONS=32``."""
    script = Path(__file__).resolve().parent / "bench_warp_side_by_side.py"
    args = ["--models", "1,2", "--worlds", "2", "--steps", "20", "--repeat", "1"] if SMALL else ["--repeat", "2"]
    got = {}
    for name, extra in (("default_connections", {}), ("32_connections", {"CUDA_DEVICE_MAX_CONNECTIONS": "32"})):
        if left(budget) < 40:
            say(f"side_by_side.{name}", "skipped: budget")
            continue
        got[name] = _json_line([sys.executable, str(script), "--device", DEVICE, *args],
                               max(20.0, min(180.0, left(budget) - 20.0)), {**os.environ, **extra})
        say(f"side_by_side.{name}", got[name])
    if more_queues_help(got.get("default_connections"), got.get("32_connections")):
        os.environ["CUDA_DEVICE_MAX_CONNECTIONS"] = "32"
        say("side_by_side.applied", "CUDA_DEVICE_MAX_CONNECTIONS=32 for the steps after this one")


def more_queues_help(default, more, gain: float = 0.8) -> bool:
    """Whether the side-by-side figures with 32 hardware queues (``more``) step the most models at
    once, on the device alone, in at most ``gain`` of the time with the default queues: then the
    check's later steps (the reproductions) run with ``CUDA_DEVICE_MAX_CONNECTIONS=32``, and say so."""
    if not (isinstance(default, dict) and isinstance(more, dict) and default.get("rows") and more.get("rows")):
        return False
    a, b = default["rows"][-1], more["rows"][-1]
    return a["models"] == b["models"] > 1 and b["device_ms_per_step"] <= gain * a["device_ms_per_step"]


def _reproduce(tag: str, args: list[str], timeout: float, env: dict) -> dict:
    out = OUT / f"repro-{tag}"
    cmd = [sys.executable, "-c", "import sys; from undulate.cli import main; sys.exit(main(sys.argv[1:]))",
           "reproduce", "--out", str(out), *args]
    stats = OUT / f"repro-{tag}.warp-first-steps.jsonl"
    timeline = OUT / f"repro-{tag}.warp-timeline.jsonl"  # every Warp model's chunks (benchmarks/bench_warp_timeline.py)
    env = {**env, "UNDULATE_WARP_STATS": str(stats), "UNDULATE_WARP_TIMELINE": str(timeline)}
    t = time.perf_counter()
    # on a timeout: what it printed, the studies' states (stdout) and the sweeps' progress (stderr)
    rc, out, err = _run_group(cmd, max(10.0, timeout), env)
    tail = (out + err)[-3000:]
    wall = time.perf_counter() - t
    (OUT / f"repro-{tag}.log").write_text(tail)
    rec = {"args": args, "rc": rc, "wall_s": wall}
    if "warp" in args:  # where its lone swimmers stepped (on a GPU by default: the cores)
        from unittest import mock

        from undulate.execution import cores_up_to, lone_swimmers_engine
        with mock.patch.dict(os.environ, env, clear=True):
            rec["lone_swimmers"] = lone_swimmers_engine(DEVICE)
            rec["cores_up_to"] = cores_up_to(DEVICE)  # batches of at most this many scenes on the cores
    if env.get("CUDA_DEVICE_MAX_CONNECTIONS"):  # set by the side-by-side step where it helped
        rec["cuda_device_max_connections"] = env["CUDA_DEVICE_MAX_CONNECTIONS"]
    if stats.exists():  # Warp models' first steps: kernel compilation (unless cached) and graph capture
        firsts = [json.loads(x) for x in stats.read_text().splitlines() if x.strip()]
        rec["warp_models"] = len(firsts)
        rec["warp_first_steps_s"] = sum(x["first_step_s"] for x in firsts)
        rec["warp_steps_per_graph"] = sorted({x.get("steps_per_graph", 1) for x in firsts})
    if timeline.exists():  # where the Warp models' time went: how many stepped at once, a step's time then
        rec["warp_timeline"] = _timeline(timeline)
    claims = out / "claims.json"
    if claims.exists():
        c = json.loads(claims.read_text())
        rec["verdicts"] = _keyed(c.get("claims", []))
    elif out.is_dir():  # cut short: the studies it finished still have their verdicts
        rec["verdicts"], rec["verdicts_from"] = study_verdicts(out), STUDY_FILES
    state = out / "reproduce.json"
    if state.exists():
        st = json.loads(state.read_text())
        rec["studies"] = {k: {"ok": v.get("ok"), "wall_s": v.get("wall_s")} for k, v in st.get("studies", {}).items()}
    return rec


STUDY_FILES = "the finished studies' NAME.json (the reproduction was cut short)"


def _timeline(path: Path):
    """``benchmarks/bench_warp_timeline.py``'s summary of a reproduction's Warp timeline (or why there is none)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    try:
        import bench_warp_timeline as warp_timeline

        return warp_timeline.summarise(warp_timeline.load(path))
    except Exception as e:  # noqa: BLE001 - a figure missing, never the check stopped
        return f"error: {type(e).__name__}: {e}"
    finally:
        sys.path.pop(0)


def study_verdicts(out: Path) -> dict:
    """``{"study:claim": verdict}`` from the study files (``NAME.json``) of a reproduction cut short
    before its ``claims.json``: each study's own verdicts, without another study's explanation (a
    claim the sensitivity study explains reads ``fails`` there)."""
    verdicts = {}
    for f in sorted(out.glob("*.json")):
        if f.name in ("claims.json", "reproduce.json"):
            continue
        try:
            d = json.loads(f.read_text())
        except ValueError:  # being written when the run was stopped
            continue
        verdicts.update(_keyed(d.get("claims", []) if isinstance(d, dict) else []))
    return verdicts


def _keyed(claims: list) -> dict:
    """``{"study:claim": verdict}`` of claim rows (claims.json's, or a study file's)."""
    return {f"{x.get('study')}:{x.get('claim')}": x.get("verdict") for x in claims}


def compare_verdicts(cpu: dict, gpu: dict) -> dict:
    """The Warp reproduction's verdicts against the MuJoCo backend's: how many are the same, those that
    differ, those the Warp run did not reach (cut short), and, from a cut-short run's study files,
    those that fail in their study where MuJoCo's reproduction had them explained (the explaining study
    not reached: the same as far as it went)."""
    a, b = cpu.get("verdicts", {}), gpu.get("verdicts", {})
    partial = gpu.get("verdicts_from") == STUDY_FILES
    same, differ, pending, missing = 0, {}, [], []
    for k in sorted(set(a) | set(b)):
        x, y = a.get(k), b.get(k)
        if y is None:
            missing.append(k)
        elif x == y:
            same += 1
        elif partial and (x, y) == ("explained", "fails"):
            pending.append(k)
        else:
            differ[k] = [x, y]
    return {"mujoco_cpu": a, "warp": b, "same": same, "differ": differ,
            "explanation_not_reached": pending, "not_reached": missing}


def _compare(tag: str, cpu: dict, gpu: dict) -> None:
    say(f"reproduce.{tag}.verdicts", compare_verdicts(cpu, gpu))


def _file_reference(mode: str) -> dict:
    """The MuJoCo backend's reproduction in ``mode`` from ``--cpu-verdicts`` (made elsewhere from the
    same commit: MuJoCo's results are a function of the code, the parameters and the seed), or {}."""
    if CPU_VERDICTS is None:
        return {}
    return json.loads(Path(CPU_VERDICTS).read_text()).get(mode, {})


def _cpu_reference(mode: str) -> dict:
    """The MuJoCo backend's verdicts for ``mode``: ``--cpu-verdicts``, else step ``quick-cpu``'s if it
    has run; else {} (then step ``quick-cpu`` compares them when it runs, or they are compared
    afterwards, from the JSON)."""
    return _file_reference(mode) or REF.get(mode, {})


def _quick_cpu(budget: float, base: dict, reserve: float) -> None:
    """Step ``quick-cpu``: quick on the MuJoCo backend on this machine's cores (the baseline of the
    Warp runs' times, measured in the same run; on 8 or more cores the reproduction runs wide,
    :data:`undulate.studies._registry.WIDE_WORKERS`), its verdicts compared with ``--cpu-verdicts``
    (MuJoCo on another machine: they must be equal) and with the Warp quick runs made before it."""
    only = ["--only", STUDIES] if STUDIES else []
    if left(budget) < 40:
        say("reproduce.quick-cpu", "skipped: budget")
        return
    cpu = _reproduce("quick-cpu", ["--quick", *only], max(40.0, left(budget) - reserve), base)
    say("reproduce.quick.mujoco_cpu", {k: v for k, v in cpu.items() if k != "verdicts"})
    REF.setdefault("quick", cpu)
    ref = _file_reference("quick").get("verdicts")
    if ref is not None and cpu.get("verdicts"):
        # with --studies (or cut short) the other claims are 'not_reached'
        c = compare_verdicts({"verdicts": ref}, cpu)
        say("reproduce.quick-cpu.against_reference", {k: v for k, v in c.items() if k not in ("mujoco_cpu", "warp")})
    for step, gpu in WARP.items():
        if step.startswith("quick") and not _file_reference("quick"):
            _compare(step, cpu, gpu)


def reproduction(step: str, budget: float) -> None:
    """One of the steps ``quick-cpu``, ``quick-warp``, ``quick-warp-warm`` (again in a fresh folder:
    every kernel now cached, so its wall time is stepping), ``full-warp``."""
    base = {k: v for k, v in os.environ.items() if k not in ("UNDULATE_BACKEND", "UNDULATE_DEVICE")}
    only = ["--only", STUDIES] if STUDIES else []
    # time kept for the steps after this one: a cold quick leaves room for the rest; the full
    # reproduction takes what is left but a warm quick's and the cores' quick's worth where they follow
    later = LATER.get(step, ())
    reserve = {"quick-warp": 200.0 if later else 10.0, "full-warp": 150.0 * ("quick-warp-warm" in later) + 80.0 * ("quick-cpu" in later),
               "quick-warp-warm": 80.0 if "quick-cpu" in later else 10.0, "quick-cpu": 10.0}[step]
    if step == "quick-cpu":
        _quick_cpu(budget, base, reserve)
        return
    mode = "quick" if step.startswith("quick") else "full"
    if left(budget) < 40:
        say(f"reproduce.{step}", "skipped: budget")
        return
    gpu = _reproduce(step, [f"--{mode}", *only, "--backend", "warp", "--device", DEVICE],
                     max(40.0, left(budget) - reserve), base)
    say(f"reproduce.{step}", {k: v for k, v in gpu.items() if k != "verdicts"})
    WARP[step] = gpu
    _compare(step, _cpu_reference(mode), gpu)


STEPS = ("pair", "full-warp", "quick-warp-warm", "quick-cpu", "quick-warp", "pair-throughput", "pack",
         "pack-throughput", "determinism", "sweep", "side-by-side")
"""The default order: issue 37's goals first (the full reproduction, which compiles the kernels, then
quick with them cached, then quick on the machine's cores, the baseline measured in the same run), as
the H200 check of 2026-11-27 already measured the throughput."""
LATER: dict = {}  # step -> the steps --only puts after it


def main() -> None:
    global OUT, DEVICE, SMALL, STUDIES, CPU_VERDICTS
    p = argparse.ArgumentParser()
    p.add_argument("out")
    p.add_argument("--budget-s", type=float, default=450.0)
    p.add_argument("--skip-full", action="store_true")
    p.add_argument("--only", default=",".join(STEPS), help="steps, in this order: " + ", ".join(STEPS))
    p.add_argument("--device", default="cuda")
    p.add_argument("--studies", default="", help="reproduce only these studies (comma-separated)")
    p.add_argument("--cpu-verdicts", default=None, help="JSON {mode: {verdicts: {...}}} of the MuJoCo "
                   "backend's reproductions from this commit (benchmarks/bench_gpu_check_reference.py)")
    p.add_argument("--dry-run", action="store_true", help="tiny sizes (a check of this script)")
    a = p.parse_args()
    DEVICE, SMALL, STUDIES, CPU_VERDICTS = a.device, a.dry_run, a.studies, a.cpu_verdicts
    OUT = Path(a.out)
    OUT.mkdir(parents=True, exist_ok=True)
    import mujoco

    from undulate.simulation._warp import versions

    say("versions", {"python": sys.version.split()[0], "mujoco": mujoco.__version__, "warp": versions(),
                     "cores": os.cpu_count()})
    if CPU_VERDICTS is not None:  # a reference made from other code is reported, not used silently
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from bench_gpu_check_reference import src_digest

        mine = src_digest()
        ref = json.loads(Path(CPU_VERDICTS).read_text())
        say("cpu_reference_same_code", {m: r.get("src_sha256") == mine for m, r in ref.items()})
    steps = [x for x in a.only.split(",") if x]
    LATER.update({x: tuple(steps[i + 1:]) for i, x in enumerate(steps)})
    for step in steps:
        # the steps that measure the Warp backend itself step every batch on Warp, however small (on a GPU
        # a batch of up to one scene per core steps on the cores by default: cores_up_to); only this
        # setting is put back after the step (a fallback the pair step turns stays for the later steps)
        own = step in ("pair", "pack", "determinism") and CORES_UP_TO_ENV not in os.environ
        if own:
            os.environ[CORES_UP_TO_ENV] = "0"
        try:
            _step(step, a.budget_s)
        except Exception:  # noqa: BLE001 - one failed step does not lose the others
            import traceback

            say(f"{step}.error", traceback.format_exc()[-2000:])
        finally:
            if own:
                os.environ.pop(CORES_UP_TO_ENV, None)
    say("total_s", time.perf_counter() - T0)


def _step(step: str, budget_s: float) -> None:
    """Run one of :data:`STEPS`."""
    if step in ("pair", "pack"):
        agreement(step)
    elif step.endswith("-throughput"):
        throughput(step.split("-")[0], budget_s)
    elif step == "determinism":
        determinism(budget_s)
    elif step == "sweep":
        sweep(budget_s)
    elif step == "side-by-side":
        side_by_side(budget_s)
    else:
        reproduction(step, budget_s)


if __name__ == "__main__":
    main()
