"""The MuJoCo Warp backend (undulate.simulation._warp) against the MuJoCo backend, on Warp's CPU device.

CI has no GPU: these tests step MuJoCo Warp's kernels on the CPU (compiled once per machine and
cached under ~/.cache/warp; the first test pays ~40 s for it).  The same code steps on CUDA in
benchmarks/gpu_check.sh.
"""

from __future__ import annotations

import functools
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from undulate import Scene, SimOptions
from undulate.errors import ParameterError
from undulate.scene import build
from undulate.simulation import resolve_options, simulate, simulate_batch

warp = pytest.importorskip("warp", reason="the gpu extra (mujoco-warp, warp-lang) is not installed")
pytest.importorskip("mujoco_warp")

WARP = dict(backend="warp", device="cpu")


def _max_dx(a, b, var="x") -> float:
    return float(np.abs(a[var].values - b[var].values).max())


@pytest.mark.parametrize("heading_guide", [False, True])
def test_affine_servo_with_slew_on_the_stream_equals_mujocos_pid(heading_guide):
    """The Warp model's servo (affine position servo, set-point slew applied to the control stream)
    is MuJoCo's pid servo: both stepped by CPU MuJoCo agree to rounding over 3000 steps, start
    included (where the 6 rad/s slew limit acts); also the heading guide's pid (no slew state)."""
    import mujoco

    from undulate.simulation._warp_servo import AffineServoTable

    sc = Scene(phases_rad=(0.0, 1.57), heading_guide=heading_guide)
    dt = resolve_options(sc, SimOptions(duration_s=2)).timestep_s
    pid, aff = build(sc, dt), build(sc, dt, servo="affine")
    k = 3000
    u = pid.controls(np.arange(k) * dt)
    servos = AffineServoTable(pid.model, aff.model, dt, [pid.model])
    table, slewed = servos.table(u[None], np.zeros((1, len(servos.act))))
    da, db = mujoco.MjData(pid.model), mujoco.MjData(aff.model)
    worst_q = worst_act = 0.0
    has = servos.act >= 0  # the servos with a slew state (the heading guide has none)
    order = np.argsort(servos.act[has])
    for i in range(k):
        da.ctrl[:] = u[i]
        db.ctrl[:] = table[i, 0]
        mujoco.mj_step(pid.model, da)
        mujoco.mj_step(aff.model, db)
        worst_q = max(worst_q, float(np.abs(da.qpos - db.qpos).max()))
        worst_act = max(worst_act, float(np.abs(da.act - slewed[0, i][has][order]).max()))
    assert worst_act < 1e-6  # float32 table: the slew states as MuJoCo's act
    assert worst_q < 1e-5  # m / rad, over 2 s (float32 set-points)
    # the slew limit did act at the start (a straight body told to take the gait's shape)
    assert np.abs(np.diff(slewed[0][:, has], axis=0)).max() <= 6.0 * dt * (1 + 1e-9)
    assert np.abs(u[1:, servos.src_pos[has]] - slewed[0, 1:][:, has]).max() > 0.1


@pytest.mark.parametrize("heading_guide, shuffled", [(False, False), (True, False), (False, True)])
def test_the_control_table_is_bitwise_the_gathered_one(heading_guide, shuffled):
    """The Warp control table is built step-major with slices where the columns are evenly spaced;
    bitwise the plain gather: per scene, the slewed position command plus (kv/kp) times the velocity
    command on each servo, the other inputs (the heading guide's) copied."""
    from undulate.simulation._warp_servo import AffineServoTable, slew

    sc = Scene(phases_rad=(0.0, 1.57), heading_guide=heading_guide)
    dt = resolve_options(sc, SimOptions(duration_s=2)).timestep_s
    pid, aff = build(sc, dt), build(sc, dt, servo="affine")
    servos = AffineServoTable(pid.model, aff.model, dt, [pid.model] * 3)
    if shuffled:  # columns not evenly spaced (gathers), and inputs copied as they are
        servos.src_vel = servos.src_vel[::-1].copy()
        servos.copy_src, servos.copy_dst = np.array([1, 2, 6]), np.array([0, 3, 1])
    rng = np.random.default_rng(1)
    u = rng.normal(size=(3, 50, pid.model.nu))
    act0 = rng.normal(size=(3, len(servos.act)))
    table, slewed = servos.table(u, act0)
    want = np.zeros((50, 3, aff.model.nu), np.float32)
    want[:, :, servos.copy_dst] = u[:, :, servos.copy_src].transpose(1, 0, 2)
    s = slew(u[:, :, servos.src_pos], servos.rate, act0)
    want[:, :, servos.dst] = (s + servos.ratio[:, None] * u[:, :, servos.src_vel]).transpose(1, 0, 2)
    assert np.array_equal(table, want) and np.array_equal(slewed, s)
    assert heading_guide == bool((servos.act < 0).any())  # the heading guide's pid has no slew state


def test_the_device_model_is_the_affine_scene_derived_without_compiling_again(monkeypatch):
    """The Warp model derived from the host's compiled ``pid`` model
    (:func:`undulate.simulation._warp_servo.device_model`) is the scene compiled with
    ``servo="affine"`` in every field MuJoCo Warp carries, but for what compilation fixes: the host's
    control layout (``nu``; the table's columns are :func:`device_inputs`) and its slew states
    (``na``, read by no actuator).  CPU MuJoCo steps the two bitwise alike under the same control
    table (slew limit acting at the start, heading guide, pushes, servo-torque sensors, resistive
    drag's inputs); deriving it compiles nothing and leaves the host's model as it was."""
    import mujoco

    from undulate.params import Ground
    from undulate.simulation._warp_private import private_api
    from undulate.simulation._warp_servo import AffineServoTable, device_inputs, device_model

    scenes = [Scene(phases_rad=(0.0, 1.57), heading_guide=True),
              Scene(phases_rad=(0.0, 1.0, 2.0), ground=Ground(mode="resistive"), forces_N=(0.05, 0.0, -0.05))]
    ctrl_rows = {"actuator_ctrllimited", "actuator_ctrlrange"}  # one row per control input
    sizes = {"nu", "na", "actuator_ctrladr", "key_act", "key_ctrl"}  # what the control layout fixes
    for sc in scenes:
        dt = resolve_options(sc, SimOptions(duration_s=1)).timestep_s
        pid, aff = build(sc, dt, push=True, loads=True), build(sc, dt, push=True, loads=True, servo="affine")
        host_before = {n: getattr(pid.model, n).copy() for n in ("actuator_gaintype", "actuator_ctrlnum")}
        compiles = []
        monkeypatch.setattr(mujoco.MjSpec, "compile", lambda *a, **k: compiles.append(a))
        dev = device_model(pid.model)
        monkeypatch.undo()
        assert not compiles
        for n, v in host_before.items():
            assert np.array_equal(getattr(pid.model, n), v), n
        cols = device_inputs(dev)
        assert len(cols) == aff.model.nu < dev.nu == pid.model.nu and dev.na == pid.model.na > 0 == aff.model.na
        assert np.array_equal(np.searchsorted(cols, dev.actuator_ctrladr), aff.model.actuator_ctrladr)
        compared = 0
        for n in sorted(private_api().model_fields - sizes):
            want = getattr(aff.model, n, None)
            if not isinstance(want, np.ndarray):
                continue
            got = getattr(dev, n)[cols] if n in ctrl_rows else getattr(dev, n)
            assert got.shape == want.shape and got.tobytes() == want.tobytes(), n
            compared += 1
        assert compared > 100
        k = 400
        u = pid.controls(np.arange(k) * dt)
        u[:, pid.index.ctrl_push.ravel()] = 0.02
        servos = AffineServoTable(pid.model, dev, dt, [pid.model])
        act0 = np.zeros((1, len(servos.act)))
        table, _ = servos.table(u[None], act0)
        want_table, _ = AffineServoTable(pid.model, aff.model, dt, [pid.model]).table(u[None], act0)
        assert np.array_equal(table, want_table)
        da, db = mujoco.MjData(aff.model), mujoco.MjData(dev)
        for i in range(k):
            da.ctrl[:] = table[i, 0]
            db.ctrl[cols] = table[i, 0]
            mujoco.mj_step(aff.model, da)
            mujoco.mj_step(dev, db)
        assert np.abs(da.qpos).max() > 0 and np.array_equal(da.qpos, db.qpos) and np.array_equal(da.qvel, db.qvel)
        assert np.array_equal(da.sensordata, db.sensordata)


def test_preparing_a_warp_batch_compiles_no_scene(monkeypatch):
    """:meth:`WarpBackend.prepare` takes the batch as the host compiled it (two distinct pair scenes)
    and compiles none of them again: its Warp models are derived from those models."""
    import mujoco

    from undulate.params import Channel
    from undulate.simulation import backend

    eng = backend("warp")
    scenes = [Scene(phases_rad=(0.0, 1.0), channel=Channel(width_m=w)) for w in (0.13, 0.14)]
    opts = [resolve_options(sc, SimOptions(duration_s=0.1, **WARP)) for sc in scenes]
    compiled = [eng.compile(sc, o, push=False, loads=False) for sc, o in zip(scenes, opts)]
    compiles = []
    real = mujoco.MjSpec.compile
    monkeypatch.setattr(mujoco.MjSpec, "compile", lambda spec, *a, **k: (compiles.append(1), real(spec, *a, **k))[1])
    runner = eng.prepare(compiled, opts[0])
    try:
        assert compiles == [] and len(runner.groups) == 1 and runner.groups[0].nu == compiled[0].model.nu // 2
    finally:
        runner.close()


def test_the_slew_rule_without_a_python_step_per_step_is_bitwise_the_step_by_step_rule():
    """:func:`undulate.simulation._warp_servo.slew` copies the steps where the state stays on its command;
    against MuJoCo's rule applied step by step: ramps from far off, jumps mid-chunk, plateaus, sign
    crossings (where ``t + (t' - t)`` can miss ``t'``), unlimited servos, empty chunks -- bitwise."""
    from undulate.simulation._warp_servo import slew

    def step_by_step(target, rate, act0):
        finite = np.isfinite(rate)
        s, r, out = np.where(finite, act0, 0.0), np.where(finite, rate, 0.0), np.empty_like(target)
        for i in range(target.shape[1]):
            s = np.where(finite, s + np.clip(target[:, i] - s, -r, r), target[:, i])
            out[:, i] = s
        return out

    rng = np.random.default_rng(0)
    copied = 0
    for trial in range(120):
        nb, k, ns = rng.integers(1, 5), rng.integers(0, 300), rng.integers(1, 4)
        t = np.linspace(0.0, rng.uniform(1, 5), k)
        target = rng.uniform(0.2, 1.0, (nb, 1, ns)) * np.sin(2 * np.pi * t[None, :, None] / rng.uniform(0.5, 3)
                                                              + rng.uniform(0, 6, (nb, 1, ns)))
        if trial % 3 == 0:
            target[:, k // 2:] += rng.uniform(-1, 1, (nb, 1, ns))
        if trial % 5 == 0:
            target = np.round(target, 2)
        rate = rng.choice([0.001, 0.01, 0.05, np.inf], (nb, ns))
        act0 = rng.uniform(-1, 1, (nb, ns))
        want = step_by_step(target, rate, act0)
        assert np.array_equal(slew(target, rate, act0), want), trial
        copied += int((want == target).all(axis=(0, 2)).sum())
    assert copied > 1000  # the copying path was taken


def test_pair_agrees_with_mujoco_over_5_s():
    """The default pair, 5 s: centres within 1 mm of the MuJoCo backend (float32, no DIAGEXACT)."""
    sc = Scene(phases_rad=(0.0, math.pi / 2))
    a = simulate(sc, SimOptions(duration_s=5.0))
    b = simulate(sc, SimOptions(duration_s=5.0, **WARP))
    assert b.attrs["backend"] == "warp" and b.attrs["device"] == "cpu" and b.attrs["precision"] == "float32"
    assert a.attrs["backend"] == "mujoco" and a.attrs["precision"] == "float64"
    assert _max_dx(a, b, "x") < 1e-3 and _max_dx(a, b, "y") < 1e-3
    assert _max_dx(a, b, "joint_angle") < 2e-3  # rad
    assert float(b["penetration"].max()) < 1e-3  # the contact model's 1 mm rule
    # the pair touches: the contact force is there on both, within 5 % of the peak
    fa, fb = a["contact_force_pair"].values, b["contact_force_pair"].values
    assert fa.max() > 1.0 and np.abs(fa - fb).max() < 0.05 * fa.max()


def _without_diagexact(monkeypatch):
    """Build scenes without MuJoCo's exact constraint regularisation (DIAGEXACT), as the Warp model is."""
    import mujoco

    import undulate.scene as scene_module

    real = scene_module.scene_spec

    def spec(*args, **kw):
        sp, walls = real(*args, **kw)
        sp.option.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_DIAGEXACT)
        return sp, walls

    monkeypatch.setattr(scene_module, "scene_spec", spec)
    from undulate.simulation._compile import clear_model_cache

    clear_model_cache()  # models compiled before the patch are not the ones asked for now


def test_a_closed_loop_controller_steps_on_warp():
    """A self-oscillating pair (closed loop: the controller senses between control periods, each period
    one Warp call) agrees with the MuJoCo backend."""
    from undulate.params import ControllerParams

    sc = Scene(phases_rad=(0.0, 1.57), controller=ControllerParams(kind="self-oscillating"))
    a = simulate(sc, SimOptions(duration_s=0.5))
    b = simulate(sc, SimOptions(duration_s=0.5, **WARP))
    assert _max_dx(a, b, "x") < 1e-3 and _max_dx(a, b, "joint_angle") < 5e-3


def test_the_h_probes_batch_steps_on_warp_as_one_model_and_agrees_with_mujoco(monkeypatch):
    """The phase-interaction probe's batched sweep function (a sensing open-loop controller over a
    batch, the whole chunk one Warp call): three held phase differences, positions held and free, give
    the MuJoCo backend's H(dphi) within 0.01 rad/s (|H| up to ~0.5 rad/s here), from two Warp models."""
    from undulate.simulation import _warp
    from undulate.studies import _phase_probe

    pts = [{"dphi_rad": d, "hold_x": h} for d, h in ((-2.0, True), (0.5, False), (1.5, True))]
    ref = _phase_probe.probe_runs(pts, [0] * 3, duration_s=6.0)
    models = []
    real = _warp.WarpRollout.__init__

    def counted(self, *args, **kwargs):
        models.append(self)
        real(self, *args, **kwargs)

    monkeypatch.setattr(_warp.WarpRollout, "__init__", counted)
    monkeypatch.setenv("UNDULATE_BACKEND", "warp")
    monkeypatch.setenv("UNDULATE_DEVICE", "cpu")
    got = _phase_probe.probe_runs(pts, [0] * 3, duration_s=6.0)
    assert len(models) == 2  # one per hold_x
    assert max(abs(float(r["H"].max())) for r in ref) > 0.3  # contact: a real interaction to agree on
    for a, b in zip(ref, got):
        assert float(abs(a["H"] - b["H"]).max()) < 0.01


def test_a_group_of_4_agrees_with_mujoco_within_its_own_sensitivity(monkeypatch):
    """Four swimmers (phases j pi/3), 5 s.  Until a contact event near t = 2.3 s the Warp run is within
    0.2 mm of MuJoCo's (both without DIAGEXACT).  That event amplifies any perturbation: float32 then
    moves the centres by up to 7 mm, while DIAGEXACT alone moves MuJoCo's own run by ~15 mm.  The test
    asserts both: agreement before the event, and Warp's difference after it below the one
    MuJoCo's own regularisation option makes (docs/gpu.md)."""
    sc = Scene(phases_rad=tuple(j * math.pi / 3 for j in range(4)))
    opts = dict(duration_s=5.0, sample_rate_hz=10.0)
    exact = simulate(sc, SimOptions(**opts))
    w = simulate(sc, SimOptions(**opts, **WARP))
    _without_diagexact(monkeypatch)
    plain = simulate(sc, SimOptions(**opts))
    t = plain["time"].values
    d_warp = np.abs(w["x"].values - plain["x"].values).max(axis=1)
    d_diag = np.abs(exact["x"].values - plain["x"].values).max(axis=1)
    assert d_warp[t <= 2.0].max() < 1e-3
    assert d_warp.max() < 0.5 * d_diag.max()  # measured: 7 mm against 15 mm
    assert float(w["penetration"].max()) < 1e-3


@pytest.mark.slow  # ~30 s on Warp's CPU device; MuJoCo's own pack check is in the default run (test_timestep_contact)
def test_a_jammed_pack_keeps_the_1_mm_rule():
    """A jammed 50-swimmer pack (rho~ = 3, the packing study's densest) for 2 s: no contact deeper
    than 1 mm, no capacity overflow (undulate.simulation._warp.capacities), and the pack stays in the channel."""
    from undulate.studies.packing import _pack

    sc = _pack({"phi_max_rad": math.pi, "rho_tilde": 3.0, "draw": 0}, amplitude_m=0.05226, base_seed=0,
               n_swimmers=50)[0]
    ds = simulate(sc, SimOptions(duration_s=2.0, sample_rate_hz=10.0, record=("y", "penetration"), **WARP))
    assert float(ds["penetration"].max()) <= 1e-3
    half = sc.channel.width_m / 2
    assert float(np.abs(ds["y"]).max()) < half


def test_a_batch_of_different_channels_is_one_warp_model_with_per_world_fields():
    """Scenes that differ in channel width and drag share one Warp model (the fields given per world,
    and the static walls' poses per world in the Data: MuJoCo Warp never recomputes them); each world
    agrees with its scene stepped alone on the MuJoCo backend (a wall left at the first world's width
    moved a pair by 4.7 mm)."""
    from undulate.simulation import _warp_worlds
    from undulate.params import Channel, ContactModel, Ground, Servo

    scenes = [Scene(phases_rad=(0.0, 1.0), channel=Channel(width_m=w), ground=Ground(drag_N_s_per_m=g),
                    servo=Servo(kp_Nm_per_rad=kp), contact=ContactModel(timeconst_s=tc))
              for w, g, kp, tc in ((0.13, 1.0, 10.0, None), (0.12, 1.5, 10.0, None), (0.14, 1.0, 8.0, None),
                                   (0.13, 1.0, 10.0, 0.004))]
    opts = SimOptions(duration_s=0.5)
    ref = [simulate(sc, opts) for sc in scenes]
    from undulate.simulation import compile_scene

    from undulate.simulation._warp_servo import device_model

    groups = _warp_worlds.plan_worlds([device_model(compile_scene(sc, resolve_options(sc, opts)).model)
                                       for sc in scenes])
    assert len(groups) == 1 and {"geom_pos", "opt.viscosity", "actuator_gainprm",
                                 "geom_solref"} <= set(groups[0][1])
    got = simulate_batch(scenes, SimOptions(duration_s=0.5, **WARP))
    for sc, r, g in zip(scenes, ref, got):
        alone = simulate(sc, SimOptions(duration_s=0.5, **WARP))
        assert _max_dx(alone, g, "y") < 1e-9 and _max_dx(alone, g, "x") < 1e-9  # its world is its run alone
        assert _max_dx(r, g, "y") < 1e-3


def test_scenes_that_differ_in_their_start_offset_are_one_warp_model():
    """Pair scenes that differ in dx0 differ in ``dof_length`` by ~1e-17, a field MuJoCo Warp cannot give
    per world but reads only for island sleeping, which our models leave off: they are one Warp model
    (until 2026-11-30 ~5, stepped one after another), and each world is its scene's run alone."""
    from undulate.simulation import _warp_worlds, compile_scene
    from undulate.simulation._warp_servo import device_model

    scenes = [Scene(phases_rad=(0.0, 1.0), dx0_m=x) for x in (-0.27, -0.09, 0.0, 0.18)]
    opts = SimOptions(duration_s=0.3, **WARP)
    models = [device_model(compile_scene(sc, resolve_options(sc, opts)).model) for sc in scenes]
    assert len({m.dof_length.tobytes() for m in models}) > 1  # what used to split them
    assert [len(idx) for idx, _ in _warp_worlds.plan_worlds(models)] == [4]
    got = simulate_batch(scenes, opts)
    for sc, g in zip(scenes, got):
        assert _max_dx(simulate(sc, opts), g) < 1e-9


def test_dof_length_is_read_by_island_sleeping_alone_in_the_installed_mujoco_warp():
    """What lets :data:`undulate.simulation._warp_worlds.ONLY_WITH_FLAG` leave ``dof_length`` out of a Warp
    model's grouping: no code of the installed MuJoCo Warp names it outside its declaration and the
    sleep module (a release that reads it elsewhere fails here)."""
    import io
    import pathlib
    import tokenize

    import mujoco_warp

    from undulate.simulation import _warp_worlds

    root = pathlib.Path(mujoco_warp.__file__).parent
    readers = set()
    for path in root.rglob("*.py"):
        if path.name.endswith("_test.py"):
            continue
        toks = tokenize.generate_tokens(io.StringIO(path.read_text()).readline)
        if any(t.type == tokenize.NAME and t.string == "dof_length" for t in toks):
            readers.add(path.relative_to(root).as_posix())
    assert readers - {"_src/types.py"} == {"_src/sleep.py"}
    assert set(_warp_worlds.ONLY_WITH_FLAG) == {"dof_length"}


def test_the_warp_models_of_one_batch_are_launched_before_any_is_collected(monkeypatch):
    """A batch whose worlds need several Warp models (here: dof_length counted, as before 2026-11-30)
    launches every model's chunk before it waits for any (on a GPU they step side by side on their
    streams), and each world is the same as in one model."""
    from undulate.simulation import _warp, _warp_worlds

    scenes = [Scene(phases_rad=(0.0, 1.0), dx0_m=x) for x in (-0.27, -0.09, 0.0, 0.18)]
    opts = SimOptions(duration_s=0.3, **WARP)
    one = simulate_batch(scenes, opts)
    monkeypatch.setattr(_warp_worlds, "ONLY_WITH_FLAG", {})
    calls: list[str] = []
    for name in ("launch", "collect"):
        real = getattr(_warp._Group, name)
        monkeypatch.setattr(_warp._Group, name, lambda self, *a, _real=real, _name=name: (
            calls.append(_name), _real(self, *a))[1])
    got = simulate_batch(scenes, opts)
    k = calls.index("collect")  # the Warp models: each chunk launches all k, then collects all k
    assert k >= 2 and calls == (["launch"] * k + ["collect"] * k) * (len(calls) // (2 * k))
    for a, b in zip(one, got):
        assert _max_dx(a, b) < 1e-9 and _max_dx(a, b, "y") < 1e-9


def _count_batches(monkeypatch) -> list[int]:
    """The calls of each gathered batch stepped in this process from now on (a list it fills)."""
    from undulate import simulation

    batches: list[int] = []
    real = simulation.Gather._run
    monkeypatch.setattr(simulation.Gather, "_run", lambda self, reqs: (batches.append(len(reqs)), real(self, reqs)))
    return batches


def test_a_warp_sweep_steps_its_runs_together_and_never_serves_mujoco_runs(tmp_path, monkeypatch):
    """On the Warp backend a sweep's runs are gathered into one batch (one world each); its store
    records the backend, and switching backend recomputes instead of reusing.  The batch's Warp model
    is named in the timeline by its sweep's folder (``STUDY/SWEEP``)."""
    from undulate.studies._runners import group_point
    from undulate.sweep import Grid, run_sweep

    fn = functools.partial(group_point, duration_s=1.0)
    grid = Grid(points=[{"dphi_rad": d} for d in (0.0, 2.0)], seed=0)
    where = tmp_path / "groups" / "s"
    cpu = run_sweep(fn, grid, where, workers=1, progress=False)
    assert cpu.identity["backend"] == "mujoco"
    batches = _count_batches(monkeypatch)
    monkeypatch.setenv("UNDULATE_BACKEND", "warp")
    monkeypatch.setenv("UNDULATE_DEVICE", "cpu")
    monkeypatch.setenv("UNDULATE_WARP_TIMELINE", str(tmp_path / "timeline.jsonl"))
    gpu = run_sweep(fn, grid, where, progress=False)
    assert gpu.identity["backend"].startswith("warp cpu float32")
    assert gpu.n_computed == 2 and gpu.n_reused == 0 and gpu.stale  # the MuJoCo runs were not served
    assert batches == [2]  # both runs' simulations in one batch
    lines = [json.loads(x) for x in (tmp_path / "timeline.jsonl").read_text().splitlines()]
    assert {(x["label"], x["nworld"]) for x in lines} == {("groups/s", 2)}
    a = cpu.dataset["x"].values
    b = gpu.dataset["x"].values
    assert np.abs(a - b).max() < 3e-3  # m, at the group runs' 2 ms step
    # each world of the gathered batch is its run alone on the Warp backend
    for i, d in enumerate((0.0, 2.0)):
        alone = fn({"dphi_rad": d}, 0)["x"].values
        assert np.abs(gpu.dataset["x"].isel(point=i, replicate=0).values - alone).max() < 1e-9


@pytest.mark.slow  # ~20 s on Warp's CPU device; the rollout contract of both engines stays in the default run
def test_a_warp_sweep_split_over_processes_gives_the_runs_of_one_and_leaves_the_pool_on_mujoco(tmp_path,
                                                                                              monkeypatch):
    """UNDULATE_WARP_PROCESSES=2: a Warp sweep's runs go to two processes of the local pool (given
    enough runs for each: GATHER_MIN_SPLIT), each stepping its share as one batch and saving its
    runs; every run is the one-process sweep's (each world is its run alone).  Each task names its
    backend, so the same warm processes then step a MuJoCo sweep on MuJoCo: bitwise the serial
    MuJoCo runs, not the Warp ones."""
    import undulate.sweep._sweep as sweep_mod
    from undulate.studies._runners import group_point
    from undulate.sweep import Grid, run_sweep, warm_workers

    fn = functools.partial(group_point, duration_s=0.5)
    grid = Grid(points=[{"dphi_rad": d} for d in (0.0, 1.0, 2.0, 3.0)], seed=0)
    monkeypatch.setenv("UNDULATE_BACKEND", "warp")
    monkeypatch.setenv("UNDULATE_DEVICE", "cpu")
    one = run_sweep(fn, grid, tmp_path / "one", progress=False)
    monkeypatch.setenv("UNDULATE_WARP_PROCESSES", "2")
    few = run_sweep(fn, grid, tmp_path / "few", progress=False)  # 4 runs: too few to split
    assert few.timing["executor"] == "serial"
    monkeypatch.setattr(sweep_mod, "GATHER_MIN_SPLIT", 2)
    with warm_workers(2):
        two = run_sweep(fn, grid, tmp_path / "two", progress=False)
        monkeypatch.setenv("UNDULATE_BACKEND", "mujoco")
        pooled = run_sweep(fn, grid, tmp_path / "pooled", workers=2, progress=False)
    serial = run_sweep(fn, grid, tmp_path / "serial", workers=1, progress=False)
    assert (one.timing["executor"], two.timing["executor"]) == ("serial", "local")
    assert two.identity == one.identity and two.n_computed == 4
    assert np.abs(two.dataset["x"].values - one.dataset["x"].values).max() < 1e-9
    assert pooled.identity["backend"] == serial.identity["backend"] == "mujoco"
    assert np.array_equal(pooled.dataset["x"].values, serial.dataset["x"].values)
    assert not np.array_equal(pooled.dataset["x"].values, two.dataset["x"].values)  # float32 Warp differs


@pytest.mark.slow  # ~17 s on Warp's CPU device; Dask against serial on MuJoCo stays in the default run (test_sweep)
def test_a_warp_sweep_on_dask_steps_on_warp_whatever_the_workers_were_started_with(tmp_path, monkeypatch):
    """A Dask worker has the environment it was started with, not the sweep's: each task names its
    backend, so a Warp sweep on workers started on the MuJoCo backend steps on Warp (float32: not the
    MuJoCo run, which its store would otherwise have labelled Warp).  A task whose backend its worker
    cannot step on fails each of its runs, saying why."""
    import json

    distributed = pytest.importorskip("distributed")
    from undulate.studies._runners import group_point
    from undulate.sweep import Grid, run_sweep
    from undulate.execution import Execution
    from undulate.sweep._worker import Chunk, run_chunk

    fn = functools.partial(group_point, duration_s=0.5)
    grid = Grid(points=[{"dphi_rad": 1.0}], seed=0)
    monkeypatch.delenv("UNDULATE_BACKEND", raising=False)
    with distributed.LocalCluster(n_workers=1, processes=True, threads_per_worker=1, dashboard_address=None) as cl:
        monkeypatch.setenv("UNDULATE_BACKEND", "warp")
        monkeypatch.setenv("UNDULATE_DEVICE", "cpu")
        on_dask = run_sweep(fn, grid, tmp_path / "dask", scheduler=cl.scheduler_address, progress=False)
        here = run_sweep(fn, grid, tmp_path / "here", progress=False)
    monkeypatch.delenv("UNDULATE_BACKEND")
    cpu = run_sweep(fn, grid, tmp_path / "cpu", workers=1, progress=False)
    assert on_dask.identity == here.identity and on_dask.ok
    assert np.abs(on_dask.dataset["x"].values - here.dataset["x"].values).max() < 1e-9
    assert not np.array_equal(on_dask.dataset["x"].values, cpu.dataset["x"].values)
    if warp.is_cuda_available():  # the rest needs a worker without the task's device
        return
    # a task for a device this worker lacks (CUDA, on a machine without): each run recorded as failed, why
    runs_dir = tmp_path / "nocuda"
    runs_dir.mkdir()
    out = run_chunk(Chunk(fn, str(runs_dir), tuple(grid.runs()), grid.names,
                          execution=Execution(backend="warp", device="cuda")))
    assert [o.status for o in out] == ["failed"] and "ParameterError" in out[0].error
    assert "device" in json.loads(next(runs_dir.glob("*.failed.json")).read_text())["error"]


def test_a_warp_sweep_on_dask_steps_each_tasks_runs_together(tmp_path, monkeypatch):
    """On Dask too, a Warp sweep's task is one batch of worlds (not its runs one at a time): one
    task where the runs are too few to split (GATHER_MIN_SPLIT), else one a worker thread; every run
    is the one-process sweep's.  (Workers in this process, so that the batches can be counted.)"""
    distributed = pytest.importorskip("distributed")
    from undulate.studies._runners import group_point
    from undulate.sweep import Grid, _sweep as sweep_mod, run_sweep

    fn = functools.partial(group_point, duration_s=0.5)
    grid = Grid(points=[{"dphi_rad": d} for d in (0.0, 1.0, 2.0, 3.0)], seed=0)
    batches = _count_batches(monkeypatch)
    monkeypatch.setenv("UNDULATE_BACKEND", "warp")
    monkeypatch.setenv("UNDULATE_DEVICE", "cpu")
    here = run_sweep(fn, grid, tmp_path / "here", progress=False)
    assert batches == [4]
    with distributed.LocalCluster(n_workers=1, processes=False, threads_per_worker=2, dashboard_address=None) as cl:
        batches.clear()
        whole = run_sweep(fn, grid, tmp_path / "whole", scheduler=cl.scheduler_address, progress=False)
        assert batches == [4]  # 4 runs: too few to split over the 2 threads
        monkeypatch.setattr(sweep_mod, "GATHER_MIN_SPLIT", 2)
        batches.clear()
        split = run_sweep(fn, grid, tmp_path / "split", scheduler=cl.scheduler_address, progress=False)
        assert sorted(batches) == [2, 2]
    for res in (whole, split):
        assert res.ok and res.timing["executor"] == "dask" and res.identity == here.identity
        assert np.abs(res.dataset["x"].values - here.dataset["x"].values).max() < 1e-9


def test_a_gathered_warp_sweep_shows_its_stepping_before_its_runs_end(tmp_path, monkeypatch):
    """A gathered batch's worlds all finish at its end, so the sweep's progress shows the batch's
    stepping as it goes (after each chunk): growing fractions of its simulated time, every line
    before the first run is counted; the runs are those of a sweep without a display."""
    import io
    import re

    import xarray as xr

    from undulate.studies._runners import group_point
    from undulate.sweep import Grid, _progress, run_sweep

    fn = functools.partial(group_point, duration_s=5.0)  # 2 500 steps of 2 ms: chunks of 2 000
    grid = Grid(points=[{"dphi_rad": d} for d in (0.0, 1.0, 2.0)], seed=0)
    monkeypatch.setenv("UNDULATE_BACKEND", "warp")
    monkeypatch.setenv("UNDULATE_DEVICE", "cpu")
    monkeypatch.setattr(_progress, "EVERY_S", 0.0)
    out = io.StringIO()
    shown = run_sweep(fn, grid, tmp_path / "shown", progress=True, stream=out)
    quiet = run_sweep(fn, grid, tmp_path / "quiet", progress=False)
    lines = out.getvalue().splitlines()
    pct = [int(m.group(1)) for m in (re.search(r"sweep shown: stepping 3 worlds together, (\d+)% of their", x) for x in lines) if m]
    assert pct == [0, 80, 100]  # t = 0, after the first chunk (4 of 5 s), the end
    first_count = next(i for i, x in enumerate(lines) if re.search(r"\d+/3 runs", x))
    assert max(i for i, x in enumerate(lines) if "stepping" in x) < first_count
    xr.testing.assert_identical(shown.dataset.drop_attrs(), quiet.dataset.drop_attrs())


def test_warp_processes_are_validated(monkeypatch):
    from undulate.simulation import warp_processes

    monkeypatch.delenv("UNDULATE_WARP_PROCESSES", raising=False)
    assert warp_processes() == 1
    monkeypatch.setenv("UNDULATE_WARP_PROCESSES", "4")
    assert warp_processes() == 4
    for bad in ("0", "four", "100000"):
        monkeypatch.setenv("UNDULATE_WARP_PROCESSES", bad)
        with pytest.raises(ParameterError, match="UNDULATE_WARP_PROCESSES"):
            warp_processes()


def test_chunks_of_any_length_give_the_same_run():
    """A run cut into chunks (whose last is shorter: the device buffers and the captured step are
    reused) equals the run in one chunk: the state crosses each boundary exactly (float32 both ways)."""
    sc = Scene(phases_rad=(0.0, 1.0))
    one = simulate(sc, SimOptions(duration_s=0.3, chunk_steps=100_000, **WARP))
    cut = simulate(sc, SimOptions(duration_s=0.3, chunk_steps=97, **WARP))
    assert _max_dx(one, cut) < 1e-9 and _max_dx(one, cut, "y") < 1e-9


def test_reduced_on_the_device_equals_every_step_on_the_host(monkeypatch):
    """Open-loop runs on Warp keep only each sample interval's state, deepest penetration and mean
    forces on the device: the same Dataset as recording every step and reducing on the host (states
    bitwise, forces and depths to float32 rounding), for a batch where one scene stops early."""
    scenes = [Scene(phases_rad=(0.0, 1.0)), Scene(phases_rad=(0.0, 2.5), dx0_m=0.05)]
    opts = SimOptions(duration_s=1.2, sample_rate_hz=20.0, chunk_steps=150, **WARP)
    stop = [lambda blocks: "enough" if blocks and blocks[-1]["time"][-1] >= 0.5 else None,
            lambda blocks: None]
    got = simulate_batch(scenes, opts, stop=stop)
    monkeypatch.setenv("UNDULATE_WARP_REDUCE", "0")
    ref = simulate_batch(scenes, opts, stop=stop)
    for g, r in zip(got, ref):
        assert g.sizes == r.sizes and set(g.data_vars) == set(r.data_vars)
        for name in r.data_vars:
            a, b = g[name].values, r[name].values
            if a.dtype.kind == "f":
                np.testing.assert_allclose(a, b, rtol=2e-5, atol=1e-6, err_msg=name)
            else:
                assert (a == b).all(), name
        assert _max_dx(g, r) == 0.0 and _max_dx(g, r, "y") == 0.0
    assert got[0].sizes["time"] < got[1].sizes["time"]  # the first scene stopped early
    assert float(got[1]["penetration"].max()) > 0  # in contact: depths and forces were compared


@pytest.mark.parametrize("reduce", ["1", "0"])
def test_a_stopped_scene_steps_on_the_device_under_finite_controls(monkeypatch, reduce):
    """A scene its rule has stopped still steps on the device (its steps are thrown away) under its
    rows of the control buffer, which nothing fills once it stopped; the buffer of a shorter last chunk
    is new and unset.  A world stepped under such garbage (inf after the float32 cast, NaN) could
    overflow its contact capacity, a CapacityError for the whole batch, or keep the solver iterating.
    Here the buffers start as huge numbers: the device sees only finite controls, and the runs are
    those of clean buffers."""
    import warnings

    from undulate.simulation import _warp
    from undulate.simulation._stepper import _Stepper

    monkeypatch.setenv("UNDULATE_WARP_REDUCE", reduce)
    scenes = [Scene(phases_rad=(0.0, 1.0)), Scene(phases_rad=(0.0, 2.5), dx0_m=0.05)]
    opts = SimOptions(duration_s=1.0, sample_rate_hz=20.0, chunk_steps=450, **WARP)  # last chunk shorter
    stop = [lambda blocks: "enough" if blocks and blocks[-1]["time"][-1] >= 0.3 else None, lambda blocks: None]
    ref = simulate_batch(scenes, opts, stop=stop)

    buffers, launch, tables = _Stepper._buffers, _warp._Group.launch, []

    def unset(self, k):  # what np.empty may hand back
        st, sd, u = buffers(self, k)
        u.fill(1e300)
        return st, sd, u

    def seen(self, qpos, qvel, warm, table, nstep):
        tables.append(np.isfinite(table).all())
        return launch(self, qpos, qvel, warm, table, nstep)

    monkeypatch.setattr(_Stepper, "_buffers", unset)
    monkeypatch.setattr(_warp._Group, "launch", seen)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # numpy's "overflow encountered in cast"
        got = simulate_batch(scenes, opts, stop=stop)
    assert len(tables) >= 3 and all(tables)
    assert got[0].sizes["time"] < got[1].sizes["time"]  # the first scene stopped: it was stepped idle
    for g, r in zip(got, ref):
        assert _max_dx(g, r) == 0.0 and _max_dx(g, r, "y") == 0.0


def test_a_divergence_found_on_the_device_is_diagnosed_as_on_the_host(monkeypatch):
    """A penetration bound crossed on the device stops the run with the host path's diagnosis, at the
    same time."""
    from undulate.errors import DivergenceError
    from undulate.params import ContactModel

    sc = Scene(phases_rad=(0.0, math.pi), contact=ContactModel(max_penetration_m=1e-5))
    opts = SimOptions(duration_s=2.0, **WARP)
    with pytest.raises(DivergenceError, match="time step") as dev:
        simulate(sc, opts)
    monkeypatch.setenv("UNDULATE_WARP_REDUCE", "0")
    with pytest.raises(DivergenceError, match="time step") as host:
        simulate(sc, opts)
    t = [str(e.value).split(":")[0] for e in (dev, host)]
    assert t[0] == t[1] and "interpenetration" in str(dev.value)


def _gathered(scenes, opts, starts=None):
    """Each scene simulated on its own thread (from ``starts[i]``, a Checkpoint or None), the threads'
    calls gathered (as a sweep's runs are): ``(the Gather, {index: Dataset})``."""
    import threading

    from undulate import simulation

    gather, got = simulation.Gather(len(scenes)), {}
    starts = starts or [None] * len(scenes)

    def one(i):
        try:
            got[i] = simulate_batch([scenes[i]], opts, start=starts[i])[0]
        finally:
            gather.thread_done()

    threads = [threading.Thread(target=one, args=(i,)) for i in range(len(scenes))]
    for t in threads:
        t.undulate_gather = gather
        t.start()
    for t in threads:
        t.join()
    return gather, got


def test_a_gather_of_two_structures_steps_them_side_by_side(monkeypatch):
    """Threads whose scenes differ in structure (a pair, a group of 3) are gathered into one batch
    per structure, each stepped on its own thread (on a GPU: its own stream); each result is its
    run alone."""
    import threading

    from undulate import simulation

    opts = SimOptions(duration_s=0.3, **WARP)
    scenes = [Scene(phases_rad=(0.0, 1.0)), Scene(phases_rad=(0.0, 1.0, 2.0))]
    where = []
    real = simulation.Gather._run_group
    monkeypatch.setattr(simulation.Gather, "_run_group",
                        lambda self, group: (where.append(threading.current_thread().name), real(self, group)))
    gather, got = _gathered(scenes, opts)
    assert sorted(gather.batches) == [1, 1] and len(where) == 2
    assert all(n.startswith("undulate-gather") for n in where)
    for i, sc in enumerate(scenes):
        assert _max_dx(simulate(sc, opts), got[i]) < 1e-9


def test_the_timeline_records_every_step_of_each_warp_model(monkeypatch, tmp_path, benchmark_script):
    """``UNDULATE_WARP_TIMELINE``: two structures gathered side by side are two models in the file,
    each with every step of its run (the duration over its own time step) in chunks of the batch's
    chunk length, its first chunk marked (it compiled and captured); ``benchmarks/bench_warp_timeline.py``
    reads it.  Without the variable nothing is written."""
    path = tmp_path / "timeline.jsonl"
    monkeypatch.setenv("UNDULATE_WARP_TIMELINE", str(path))
    opts = SimOptions(duration_s=0.3, chunk_steps=120, **WARP)
    scenes = [Scene(phases_rad=(0.0, 1.0)), Scene(phases_rad=(0.0, 1.0, 2.0))]
    _gathered(scenes, opts)
    tl = benchmark_script("bench_warp_timeline")
    models = tl.load(path)
    assert sorted(m["structure"][1] for m in models) == [10, 15]  # nv: the pair's, the group's
    for m in models:
        dt = m["structure"][-1]
        steps = m["chunks"][:, 2]
        assert steps.sum() == round(0.3 / dt) and (steps <= 120).all() and m["nworld"] == 1
        assert m["chunks"][:, 3].tolist() == [1] + [0] * (len(steps) - 1)
        assert (np.diff(m["chunks"][:, 0]) > 0).all() and (m["chunks"][:, 1] > 0).all()
    s = tl.summarise(models)
    assert (s["models"], s["structures"]) == (2, 2) and s["world_steps"] == sum(round(0.3 / m["structure"][-1])
                                                                                for m in models)
    monkeypatch.delenv("UNDULATE_WARP_TIMELINE")
    path.unlink()
    simulate(scenes[0], opts)
    assert not path.exists()


def test_runs_going_on_from_checkpoints_of_one_time_are_gathered_into_one_batch():
    """Calls that go on from checkpoints (the packing study's stopped runs continued) are gathered
    with those whose checkpoints have the same time, never with runs from rest or from another
    time; each run is bitwise its batch stepped without gathering."""
    from undulate import Checkpoint

    opts = SimOptions(duration_s=0.3, **WARP)
    scenes = [Scene(phases_rad=(0.0, d)) for d in (0.5, 1.0, 2.0, 3.0)]
    ends = [Checkpoint.of(simulate(sc, SimOptions(duration_s=t, **WARP)))
            for sc, t in zip(scenes[:3], (0.2, 0.2, 0.1))]
    gather, got = _gathered(scenes, opts, starts=[*ends, None])
    assert sorted(gather.batches) == [1, 1, 2]
    want = [*simulate_batch(scenes[:2], opts, start=ends[:2]), simulate(scenes[2], opts, start=ends[2]),
            simulate(scenes[3], opts)]
    for i, w in enumerate(want):
        assert (float(got[i]["time"][0]) > 0) == (i < 3)  # the first three after their checkpoints
        for v in ("time", "x", "y", "joint_error"):
            np.testing.assert_array_equal(got[i][v].values, w[v].values)


@pytest.mark.parametrize("cached", [True, False])
def test_a_gathered_batch_compiles_each_scene_once_for_grouping_and_planning(monkeypatch, cached):
    """Grouping a gathered batch compiles each call's scene to learn its structure; the batch's plan
    takes those models rather than compiling them again, and the Warp models are derived from them
    (without the model cache: one compile a scene; with it, scenes that differ only in their phases
    compile once in all), and the runs are bitwise those of the same batch not gathered."""
    from undulate.simulation import _compile

    opts = SimOptions(duration_s=0.2, **WARP)
    scenes = [Scene(phases_rad=(0.0, d)) for d in (0.5, 1.0, 2.0)]
    alone = simulate_batch(scenes, opts)
    _compile.clear_model_cache()
    if not cached:  # as in a batch of more distinct scenes than the cache keeps
        monkeypatch.setattr(_compile, "_cached_model", _compile._model)
    builds = []
    real = _compile.build
    monkeypatch.setattr(_compile, "build", lambda sc, *a, **k: (builds.append(k.get("servo", "pid")), real(sc, *a, **k))[1])
    gather, got = _gathered(scenes, opts)
    assert gather.batches == [3]
    n = 1 if cached else 3
    assert builds == ["pid"] * n
    for i in range(len(scenes)):
        for v in ("x", "y", "joint_error"):
            np.testing.assert_array_equal(got[i][v].values, alone[i][v].values)


def test_a_capacity_overflow_stops_the_run_naming_the_capacity(monkeypatch, capfd):
    """A contact sensor allowed fewer matches than the pair's contacts: the run stops with CapacityError
    naming the capacity, not with wrong forces or one warning per step.  Contacts allocated below what
    the first state has: CapacityError too, before stepping."""
    from undulate.simulation import _warp, _warp_group

    real = _warp.capacities
    sc = Scene(phases_rad=(0.0, 1.57))
    monkeypatch.setattr(_warp_group, "capacities", lambda m: {**real(m), "contact_sensor_maxmatch": 1})
    with pytest.raises(_warp.CapacityError, match="contact_sensor_maxmatch"):
        simulate(sc, SimOptions(duration_s=0.1, **WARP))
    monkeypatch.setattr(_warp_group, "capacities", lambda m: {**real(m), "nconmax": 1})
    with pytest.raises(_warp.CapacityError, match="nconmax"):
        simulate(sc, SimOptions(duration_s=0.1, **WARP))
    assert "overflow" not in capfd.readouterr().out.lower()  # no print from the kernels either


def test_the_traced_step_names_every_kernel_the_first_step_loads_and_leaves_the_data_alone(monkeypatch):
    """A Warp model's kernels are compiled on threads before its first step
    (:func:`undulate.simulation._warp_group._compile_kernels`) from a trace of the step whose launches are
    recorded, not run.  Every module the real step then launches is among those traced (so nothing is
    left to compile one after another), and the trace leaves the group's data, and its model's
    solver loop, as they were (it steps throwaway data)."""
    import mujoco
    import warp as wp

    from undulate.simulation import _warp, _warp_group, compile_scene
    from undulate.simulation._warp_servo import device_model
    from warp._src.context import _normalize_launch_dim, _resolve_launch_block_dim

    sc = Scene(phases_rad=(0.0, 1.57))
    aff = device_model(compile_scene(sc, resolve_options(sc, SimOptions(duration_s=0.1))).model)
    aff.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_DIAGEXACT)
    group = _warp._Group(aff, np.arange(3), {}, "cpu", [aff] * 3)
    fields = {n: v.numpy().copy() for n, v in vars(group.d).items() if isinstance(v, wp.array)}
    conditional = group.m.opt.graph_conditional
    traced = _warp_group._traced_modules(group)
    assert len(traced) > 20 and group.m.opt.graph_conditional == conditional
    for n, v in fields.items():
        assert np.array_equal(getattr(group.d, n).numpy(), v, equal_nan=True), n
    device = wp.get_device("cpu")
    want = {(mod, _resolve_launch_block_dim(device, bd)) for mod, bd in traced}
    launched = set()

    def recorder(real):  # the modules the step loads: those of its launches that are not empty
        def launch(kernel, *args, **kw):
            if _normalize_launch_dim(kw["dim"] if "dim" in kw else args[0])[1] > 0:
                launched.add((kernel.module, _resolve_launch_block_dim(device, kw.get("block_dim"))))
            return real(kernel, *args, **kw)
        return launch

    monkeypatch.setattr(wp, "launch", recorder(wp.launch))
    monkeypatch.setattr(wp, "launch_tiled", recorder(wp.launch_tiled))
    group._buffers(1)
    group._one_step()
    assert launched and launched <= want, sorted(m.name for m, _ in launched - want)


def test_warp_determinism_is_on_for_the_cpu_device_and_off_on_a_gpu_unless_told_otherwise(monkeypatch):
    """MuJoCo Warp's determinism (stable contact order, canonical constraint rows, order-invariant
    atomics) is on by default on Warp's CPU device and off on a GPU, where it made steps 9-20x slower
    and could not allocate for a jammed pack (H200, 2026-11-27); UNDULATE_WARP_DETERMINISTIC=1 / 0
    sets it on either, anything else is refused.  The Dataset and the sweep identity say which."""
    import mujoco
    from mujoco_warp._src.types import DeterminismType

    from undulate.simulation import _warp, compile_scene
    from undulate.simulation._warp_servo import device_model

    sc = Scene(phases_rad=(0.0, 1.57))
    aff = device_model(compile_scene(sc, resolve_options(sc, SimOptions(duration_s=0.1))).model)
    aff.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_DIAGEXACT)
    monkeypatch.delenv("UNDULATE_WARP_DETERMINISTIC", raising=False)
    assert _warp._Group(aff, np.arange(1), {}, "cpu").m.opt.deterministic == DeterminismType.ALL
    assert _warp.determinism("cpu") == DeterminismType.ALL
    assert _warp.determinism("cuda") == _warp.determinism("cuda:0") == DeterminismType.NONE
    from undulate.sweep import backend_identity

    monkeypatch.setenv("UNDULATE_BACKEND", "warp")
    monkeypatch.setenv("UNDULATE_DEVICE", "cpu")
    on = backend_identity()
    assert simulate(sc, SimOptions(duration_s=0.05, **WARP)).attrs["warp_determinism"] == "all"
    monkeypatch.setenv("UNDULATE_WARP_DETERMINISTIC", "0")
    assert _warp._Group(aff, np.arange(1), {}, "cpu").m.opt.deterministic == DeterminismType.NONE
    # a sweep's runs made with it on are never served for a request with it off (nor the reverse)
    assert backend_identity() == on.replace("float32", "float32 nondeterministic") != on
    monkeypatch.setenv("UNDULATE_WARP_DETERMINISTIC", "1")
    assert _warp.determinism("cuda") == DeterminismType.ALL
    monkeypatch.setenv("UNDULATE_WARP_DETERMINISTIC", "yes")
    with pytest.raises(ParameterError, match="UNDULATE_WARP_DETERMINISTIC"):
        _warp.determinism("cpu")


def test_determinism_beyond_warps_arrays_is_a_capacity_error_naming_the_setting(monkeypatch):
    """On a GPU, MuJoCo Warp's deterministic atomics need sort-reduce workspace that Warp could not
    allocate for a jammed pack (H200: "Array shapes must not exceed ... signed 32-bit integer"); the
    run stops with a CapacityError saying to turn the setting off, and with determinism off the same
    error is not rewritten.  (Warp's deterministic launches exist on CUDA only: the error is injected.)"""
    from undulate.simulation import _warp

    said = ("Array shapes must not exceed the maximum representable value of a signed 32-bit integer, "
            "got 2671722239 in dimension 0.")

    def refuse(self):
        raise ValueError(said)

    monkeypatch.setattr(_warp._Group, "_one_step", refuse)
    sc = Scene(phases_rad=(0.0, 1.57))
    monkeypatch.setenv("UNDULATE_WARP_DETERMINISTIC", "1")
    with pytest.raises(_warp.CapacityError, match="UNDULATE_WARP_DETERMINISTIC=0.*1 worlds|1 worlds.*UNDULATE_WARP_DETERMINISTIC=0"):
        simulate(sc, SimOptions(duration_s=0.05, **WARP))
    monkeypatch.setenv("UNDULATE_WARP_DETERMINISTIC", "0")
    with pytest.raises(ValueError, match="signed 32-bit"):
        simulate(sc, SimOptions(duration_s=0.05, **WARP))


def test_steps_in_one_graph_give_the_run_of_one_step_graphs(monkeypatch):
    """A chunk stepped by graphs of 16 steps (and one-step graphs for its remainder: a GPU's default)
    is bitwise the chunk stepped one graph per step (the CPU device's default); the setting is
    validated."""
    from undulate.simulation import _warp

    sc = Scene(phases_rad=(0.0, 1.57))
    runs = []
    for n in ("1", "16"):
        monkeypatch.setenv("UNDULATE_WARP_STEPS_PER_GRAPH", n)
        runs.append(simulate(sc, SimOptions(duration_s=0.37, **WARP)))
    for v in ("x", "y", "joint_angle", "contact_force_pair"):
        assert np.array_equal(runs[0][v].values, runs[1][v].values), v
    monkeypatch.delenv("UNDULATE_WARP_STEPS_PER_GRAPH")
    assert _warp.steps_per_graph("cuda") == _warp.STEPS_PER_GRAPH > 1 == _warp.steps_per_graph("cpu")
    for bad in ("0", "x", "5000"):
        monkeypatch.setenv("UNDULATE_WARP_STEPS_PER_GRAPH", bad)
        with pytest.raises(ParameterError, match="UNDULATE_WARP_STEPS_PER_GRAPH"):
            _warp.steps_per_graph()


def test_capacities_count_a_frictionless_contact_as_one_constraint_row():
    """A frictionless contact (condim 1, the default contact model) is one constraint row: a group
    of three overflowed 31 rows on Warp's CPU device when it was counted as none."""
    import mujoco

    from undulate.simulation import _warp, compile_scene

    sc = Scene(phases_rad=(0.0, 1.0, 2.0))
    m = compile_scene(sc, resolve_options(sc, SimOptions(duration_s=0.1)), servo="affine").model
    assert set(m.geom_condim.tolist()) == {1}
    cap = _warp.capacities(m)
    assert cap["njmax"] >= cap["nconmax"] + m.njnt
    m.geom_condim[:] = 3  # pyramidal cone: 4 rows a contact
    assert m.opt.cone == mujoco.mjtCone.mjCONE_PYRAMIDAL
    assert _warp.capacities(m)["njmax"] >= 4 * cap["nconmax"]


def test_a_failed_compile_on_threads_leaves_the_kernels_to_the_first_step(monkeypatch):
    """Compiling on threads is an optimisation: a module that fails to load there (a path never met
    on this device) is left to the first step, which loads it the Warp way; one warning says so."""
    from undulate.simulation import _warp_group

    class Broken:
        name = "broken"

        def load(self, device, block_dim=None):
            raise RuntimeError("no compiler here")

    monkeypatch.setenv("UNDULATE_WARP_COMPILE_WORKERS", "2")
    monkeypatch.setattr(_warp_group, "_traced_modules", lambda group: [(Broken(), None)])
    monkeypatch.setattr(_warp_group, "_COMPILE_FALLBACK_SAID", False)
    sc = Scene(phases_rad=(0.0, 1.57))
    with pytest.warns(RuntimeWarning, match="compiled on threads failed.*no compiler here"):
        ds = simulate(sc, SimOptions(duration_s=0.05, **WARP))
    assert np.isfinite(ds["x"].values).all()


def test_compile_workers_are_validated(monkeypatch):
    from undulate.simulation import _warp

    monkeypatch.setenv("UNDULATE_WARP_COMPILE_WORKERS", "3")
    assert _warp.compile_workers() == 3
    for bad in ("0", "two"):
        monkeypatch.setenv("UNDULATE_WARP_COMPILE_WORKERS", bad)
        with pytest.raises(ParameterError, match="UNDULATE_WARP_COMPILE_WORKERS"):
            _warp.compile_workers()
    monkeypatch.delenv("UNDULATE_WARP_COMPILE_WORKERS")
    assert _warp.compile_workers() >= 1


def test_options_validate_backend_and_device():
    with pytest.raises(ParameterError, match="backend"):
        SimOptions(backend="jax")
    with pytest.raises(ParameterError, match="device"):
        SimOptions(backend="warp", device="tpu")
    with pytest.raises(ParameterError, match="device"):
        SimOptions(backend="mujoco", device="cuda")
    if not warp.is_cuda_available():
        with pytest.raises(ParameterError, match="no CUDA device"):
            simulate(Scene(), SimOptions(duration_s=0.1, backend="warp", device="cuda"))


def test_code_hash_counts_the_selected_backend_only(monkeypatch):
    from undulate._source import code_hash
    from undulate.studies._runners import pair_point

    monkeypatch.delenv("UNDULATE_BACKEND", raising=False)
    cpu = code_hash(pair_point)
    monkeypatch.setenv("UNDULATE_BACKEND", "warp")
    assert code_hash(pair_point) != cpu


def test_every_module_only_the_warp_backend_imports_is_one_of_its_modules():
    """A module reached only through the Warp backend's modules is left out of a MuJoCo sweep's code
    hash and of the GPU check's CPU reference only if ``BACKEND_MODULES`` names it: a new module
    imported by ``_warp`` alone and not named there would make every MuJoCo result stale."""
    from undulate._source import BACKEND_MODULES, import_graph

    graph = import_graph()
    importers: dict[str, set] = {m: set() for m in graph}
    for m, deps in graph.items():
        for x in deps:
            importers[x].add(m)
    only_warp = set(BACKEND_MODULES["warp"])
    grown = True
    while grown:  # a module all of whose importers are the Warp backend's is the Warp backend's
        new = {m for m in graph if m not in only_warp and importers[m] and importers[m] <= only_warp}
        only_warp |= new
        grown = bool(new)
    assert only_warp == set(BACKEND_MODULES["warp"])


def test_backend_warp_without_the_extra_is_one_line_and_exit_2(tmp_path):
    """A machine without mujoco-warp: `--backend warp` names the extra, exit 2, no traceback, no file."""
    code = ("import sys, builtins\n"
            "real = builtins.__import__\n"
            "def imp(name, *a, **k):\n"
            "    if name.split('.')[0] in ('warp', 'mujoco_warp'):\n"
            "        raise ImportError(name)\n"
            "    return real(name, *a, **k)\n"
            "builtins.__import__ = imp\n"
            "from undulate.cli import main\n"
            "sys.exit(main(sys.argv[1:]))\n")
    out = tmp_path / "run.nc"
    for args in (["simulate", "--duration", "0.1", "--backend", "warp", "--out", str(out)],
                 ["study", "pairs", "--backend", "warp", "--out", str(tmp_path / "r")]):
        r = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=120)
        assert r.returncode == 2, r.stderr
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert len(lines) == 1 and "--backend" in lines[0] and "undulate[gpu]" in lines[0], r.stderr
        assert "Traceback" not in r.stderr
    assert not out.exists() and not (tmp_path / "r").exists()


def test_warp_on_a_machine_without_cuda_says_one_line(tmp_path):
    """Warp's C library writes a line on stderr when it finds no CUDA driver; a run on the CPU device does
    not show it, and ``--device cuda`` there is one line naming ``--device`` (exit 2, no file)."""
    r = subprocess.run([sys.executable, "-c", "from undulate.simulation import _warp\n"
                        "import sys; print(_warp.resolve_device('cpu')); print('other', file=sys.stderr)"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "cpu", r.stderr
    assert r.stderr.strip() == "other"  # Warp's own line gone, the process's own stderr intact
    if warp.is_cuda_available():
        return
    out = tmp_path / "run.nc"
    r = subprocess.run([sys.executable, "-m", "undulate.cli", "simulate", "--duration", "0.1", "--backend", "warp",
                        "--device", "cuda", "--out", str(out)], capture_output=True, text=True, timeout=120)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1 and "--device" in lines[0] and "no CUDA device" in lines[0], r.stderr
    assert not out.exists()


def test_a_scene_with_tendons_has_no_derived_device_model():
    """The derived Warp model keeps the host's control layout, which MuJoCo Warp's tendon actuation would
    misread (it launches over nu as if nu were the actuators): a model with a tendon is refused."""
    import mujoco

    from undulate.errors import UndulateError
    from undulate.simulation._warp_servo import device_model

    m = mujoco.MjModel.from_xml_string("""<mujoco><worldbody><body><joint name="a" type="hinge"/>
        <geom size="0.1" mass="1"/></body></worldbody><tendon><fixed name="t"><joint joint="a" coef="1"/>
        </fixed></tendon></mujoco>""")
    with pytest.raises(UndulateError, match="tendons"):
        device_model(m)

