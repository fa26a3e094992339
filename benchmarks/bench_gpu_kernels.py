"""Warp's GPU kernels for a reproduction, compiled here, without a GPU, before a device lease.

A cold kernel cache cost the H200 leases of 2026-11-27 100-150 s of their 15 minutes (NVRTC compiling
MuJoCo Warp's modules at each new model's first step). Warp looks a module up in its kernel cache by a
hash of the module's source and options, not of the machine, and its NVRTC compiles for any
architecture without a device (``wp.compile_aot_module``). So this script:

1. runs ``undulate reproduce`` (quick by default) on the MuJoCo backend in this process, one worker,
   recording every batch it asks for (:func:`undulate.simulation._plan_batch`);
2. for each model structure (but the lone swimmers', which a GPU steps on the cores,
   :func:`undulate.execution.lone_swimmers_engine`), builds the Warp backend's models for
   its largest batch on Warp's CPU device, with MuJoCo Warp's determinism as on a GPU
   (``UNDULATE_WARP_DETERMINISTIC``, default off there), and traces one step as the backend does
   before a first step (:func:`undulate.simulation._warp_group._traced_modules`): the modules and their
   CUDA block sizes;
3. compiles each module for ``sm_90`` (H100, H200) both ways Warp may load it there: a CUBIN, and PTX
   for ``sm_75`` (Warp's default PTX target, used where the device's driver is at least as new as
   Warp's CUDA toolkit), into ``OUTDIR/<warp version>/`` laid out as Warp's kernel cache;
4. writes ``OUTDIR/kernels.json``: the structures, the modules, the times (and keeps the recorded
   batches in ``OUTDIR/batches.pkl``: run again, it only traces and compiles).

``benchmarks/make_gpu_site.sh out/site OUTDIR`` puts them in the site tarball and ``gpu_check.sh`` copies
them into the device's kernel cache. Whether the device finds them (the same hashes on Python 3.12, the
same module set on CUDA) is for the device to show: the check's first-step times
(``warp_first_steps_s``) say it. A module it misses is compiled there as before.

    python benchmarks/bench_gpu_kernels.py OUTDIR [--full] [--arch 90]
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import shutil
import sys
import tempfile
import time
from pathlib import Path


def _record_batches(full: bool) -> dict:
    """``{structure: (n_calls, scenes of its largest call)}`` of a reproduction's batches (the structure
    key's last two entries: closed loop, pushed)."""
    import undulate.simulation._run as sim  # where simulate_batch plans its batches
    from undulate.reproduce import reproduce

    seen: dict = {}
    plan = sim._plan_batch

    def recording(scenes, options, out, controller, compiled=None):
        bt = plan(scenes, options, out, controller, compiled)
        m = bt.compiled[0].model
        # what MuJoCo Warp specialises its kernels on: the sizes, the solver and fluid options (the
        # swimming ground's ellipsoid fluid model, the viscous ground's inertia box), the servos' form
        key = (m.nq, m.nv, m.nu, m.na, m.nbody, m.ngeom, m.nsensor, m.nsensordata, m.npair, m.nexclude,
               int(m.opt.integrator), int(m.opt.cone), int(m.opt.solver), int(m.opt.jacobian),
               int(m.opt.disableflags), int(m.opt.enableflags), bool(m.opt.density > 0),
               bool(m.opt.viscosity > 0), bool(m.geom_fluid[:, 0].any()),
               bt.ctl is not None, any(s.forces_N is not None for s in scenes))
        n, best = seen.get(key, (0, []))
        seen[key] = (n + 1, list(scenes) if len(scenes) > len(best) else best)
        return bt

    sim._plan_batch = recording
    try:
        with tempfile.TemporaryDirectory() as out:
            reproduce(out, quick=not full, workers=1, log=lambda s: None)
    finally:
        sim._plan_batch = plan
    return seen


def _traced(scenes: list, closed: bool) -> list:
    """The (module, CUDA block size) pairs one step of the Warp backend's models of ``scenes`` launches."""
    from unittest import mock

    from undulate.params import SimOptions
    from undulate.simulation import _warp, _warp_group
    from undulate.simulation._batch import _Clock, _plan_batch
    from undulate.simulation._stepper import _Stepper

    controller = None
    if closed:
        from undulate.control import make_controller
        controller = make_controller(scenes[0])
    bt = _plan_batch(scenes[:64], SimOptions(backend="warp", device="cpu"), None, controller)
    # MuJoCo Warp's determinism as on a GPU (off by default there, on by default on the CPU device):
    # 12 of a pair's 41 modules and 16 of a pack's 50 differ between the two
    gpu = "1" if _warp.determinism("cuda") else "0"
    with mock.patch.dict(os.environ, {"UNDULATE_WARP_DETERMINISTIC": gpu}):
        runner = _Stepper(bt, 0, _Clock()).runner  # the backend's own models of the batch (not stepped)
    # a CUDA launch's block size: its own, else 256 (warp's _resolve_launch_block_dim; on the CPU it is 1)
    return [(mod, 256 if bd is None or bd <= 0 else int(bd))
            for g in runner.groups for mod, bd in _warp_group._traced_modules(g)]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("outdir", type=Path)
    ap.add_argument("--full", action="store_true", help="record a full reproduction's batches (default: quick)")
    ap.add_argument("--arch", type=int, default=90, help="the GPU's compute capability (default 90: H100, H200)")
    args = ap.parse_args(argv)
    os.environ.pop("UNDULATE_BACKEND", None)
    import warp as wp

    wp.config.quiet = True
    wp.config.kernel_cache_dir = str(args.outdir.resolve())
    wp.init()
    from warp._src.context import runtime

    from undulate.execution import lone_swimmers_engine

    t0 = time.perf_counter()
    batches = args.outdir / "batches.pkl"  # the recorded batches, kept: a second run only traces and compiles
    if batches.exists():
        seen = pickle.loads(batches.read_bytes())
    else:
        seen = _record_batches(args.full)
        batches.write_bytes(pickle.dumps(seen))
    t_rec = time.perf_counter() - t0
    print(f"{len(seen)} model structures in {t_rec:.0f} s", flush=True)
    modules: dict = {}
    structures = []
    lone_on_cores = lone_swimmers_engine("cuda") == "mujoco"
    for key, (n, scenes) in sorted(seen.items(), key=lambda kv: kv[0][1]):
        if lone_on_cores and all(sc.n_swimmers == 1 for sc in scenes):  # a GPU steps them on MuJoCo
            structures.append({"nv": key[1], "ngeom": key[5], "batches": n, "lone_swimmers_on_mujoco": True})
            print(f"nv {key[1]:3d} ngeom {key[5]:4d}: lone swimmers, stepped on the cores on a GPU", flush=True)
            continue
        mods = _traced(scenes, closed=key[-2])
        new = 0
        for mod, bd in mods:
            if (mod.name, bd) not in modules:
                modules[(mod.name, bd)] = mod
                new += 1
        structures.append({"nv": key[1], "nu": key[2], "ngeom": key[5], "fluid_density": key[16],
                           "ellipsoid_fluid": key[18], "closed_loop": key[19], "push": key[20],
                           "batches": n, "worlds_traced": min(len(scenes), 64), "modules": len(mods), "new": new})
        print(f"nv {key[1]:3d} ngeom {key[5]:4d}: {len(mods)} modules, {new} new", flush=True)
    ptx_arch = min(args.arch, runtime.default_ptx_arch)
    t1 = time.perf_counter()
    compiled = []
    for (name, bd), mod in modules.items():
        opts = mod.resolve_options(wp.config, block_dim=bd)
        t = time.perf_counter()
        for arch, ptx in ((args.arch, False), (ptx_arch, True)):
            mod._compile(None, None, None, arch, use_ptx=ptx, options=opts)
        compiled.append({"module": mod.get_module_identifier(block_dim=bd), "block_dim": bd,
                         "seconds": round(time.perf_counter() - t, 2)})
        print(f"{compiled[-1]['seconds']:6.2f} s {compiled[-1]['module']}", flush=True)
    root = Path(wp.config.kernel_cache_dir)
    for src in root.glob("wp_*/*.cu"):  # the CUDA sources: Warp loads the binaries and .meta only
        src.unlink()
    shutil.rmtree(root / "lto", ignore_errors=True)  # the tile kernels' link-time objects: for compiling only
    from importlib.metadata import version

    report = {"warp_lang": version("warp-lang"), "mujoco_warp": version("mujoco-warp"), "arch": args.arch,
              "ptx_arch": ptx_arch, "mode": "full" if args.full else "quick", "record_s": round(t_rec, 1),
              "compile_s": round(time.perf_counter() - t1, 1), "structures": structures, "modules": compiled,
              "cache_dir": str(root.relative_to(args.outdir.resolve()))}
    (args.outdir / "kernels.json").write_text(json.dumps(report, indent=1))
    print(f"{len(compiled)} modules for sm_{args.arch} and PTX sm_{ptx_arch} in {report['compile_s']} s: {root}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
