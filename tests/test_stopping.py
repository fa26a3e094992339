"""Stopping rules (undulate.stopping): runs that end once their answer is decided give the same
answer as the full-length run, are bitwise its prefix, and carry the rule in their identity."""

import functools
import math

import numpy as np
import pytest

from undulate import Scene, SimOptions, simulate
from undulate.params import Channel
from undulate import _walltime
from undulate.stopping import ExcessStop, PhaseStop, SteadyStop
from undulate.studies import _analysis as C
from undulate.studies._criteria import STEADY_TOL
from undulate.studies._runners import PAIR_STOP, group_point, lone_swimmer, pair_point
from undulate.studies.packing import PACKING_STOP, THRESHOLD_RAD, Resumes, packing_continue, packing_point
from undulate.sweep._store import function_id


def _finite_len(a) -> int:
    v = np.asarray(a, float).reshape(len(a), -1)[:, 0]
    return int(np.isfinite(v).sum())


def test_stopped_pair_run_is_the_full_runs_prefix_and_gives_its_offset():
    point = {"dphi_rad": math.pi / 2, "dx0_over_lambda": 0.0}
    full = pair_point(point, 0)
    short = pair_point(point, 0, stop=PAIR_STOP)
    assert float(short["stopped_at_s"]) < float(full["stopped_at_s"]) == 30.0
    assert bool(short["steady"]) and bool(full["steady"])
    assert abs(float(short["dx_final_over_lambda"]) - float(full["dx_final_over_lambda"])) <= STEADY_TOL
    assert float(short["impulse_2T_Ns"]) == float(full["impulse_2T_Ns"])  # the first two periods: bitwise
    np.testing.assert_array_equal(short["time"].values, full["time"].values)  # one axis, NaN after the stop
    n = _finite_len(short["dx_over_lambda"].values)
    assert 0 < n < full.sizes["time"]
    np.testing.assert_array_equal(short["dx_over_lambda"].values[:n], full["dx_over_lambda"].values[:n])
    assert "SteadyStop(tol=0.01, window=3, extra_periods=2" in short["stopped_at_s"].attrs["stop_rule"]
    assert full["stopped_at_s"].attrs["stop_rule"] == "none"


def test_stopped_group_run_is_bitwise_the_prefix_and_the_analysis_agrees():
    point = {"dphi_rad": math.pi / 2}
    full = group_point(point, 0)
    short = group_point(point, 0, stop=PAIR_STOP)
    assert float(short["stopped_at_s"]) < 30.0
    n = _finite_len(short["x"].values)
    assert n == int(round(float(short["stopped_at_s"]) * 10)) + 1
    for v in ("x", "y", "joint_error", "contact_force_pair"):
        np.testing.assert_array_equal(short[v].values[:n], full[v].values[:n], err_msg=v)
        assert np.isnan(short[v].values[n:]).all()
    lam = float(full["wavelength"])
    a, _ = C.pair_record(full, math.pi / 2, lam, 0.052)
    b, series = C.pair_record(short, math.pi / 2, lam, 0.052)
    assert a["steady"] == b["steady"] == 1.0
    assert abs(a["dx_steady"] - b["dx_steady"]) / lam <= C.STEADY_TOL
    assert len(series) == full.sizes["time"] and np.isnan(series[n:]).all()


def test_a_different_rule_is_a_different_sweep():
    base = functools.partial(pair_point, duration_s=30.0)
    ids = {function_id(base), function_id(functools.partial(base, stop=PAIR_STOP)),
           function_id(functools.partial(base, stop=SteadyStop(extra_periods=3)))}
    assert len(ids) == 3


def test_simulate_records_its_stop_and_its_physics_time():
    calls = []

    def stop(blocks):
        calls.append(float(blocks[0]["time"][-1]))
        return "enough" if calls[-1] >= 3.0 else None

    sc = Scene(phases_rad=(0.0, 1.0), channel=Channel(width_m=0.13))
    opt = SimOptions(duration_s=10.0, timestep_s=0.002, chunk_steps=500)
    with _walltime.meter() as tally:
        ds = simulate(sc, opt, stop=stop)
    assert calls[0] == 0.0 and ds.attrs["stop_reason"] == "enough"
    assert ds.attrs["stopped_at"] == pytest.approx(3.0)
    assert ds.attrs["physics_steps"] == 1500 == tally.steps  # one scene, 3 s of 2 ms steps
    assert 0 < ds.attrs["physics_time"] == tally.seconds
    ref = simulate(sc, SimOptions(duration_s=10.0, timestep_s=0.002))
    for v in ds.data_vars:
        np.testing.assert_array_equal(ds[v].values, ref[v].values[:ds.sizes["time"]], err_msg=v)
    assert ref.attrs["stop_reason"] == "" and ref.attrs["stopped_at"] == pytest.approx(10.0)


def test_a_stopped_run_goes_on_from_its_checkpoint_bitwise_as_the_uninterrupted_run():
    """simulate(start=Checkpoint.of(stopped)) records the samples after the stop: with the stopped
    run's, bitwise the run that never stopped (state and warm start carry everything), and it steps
    only the rest."""
    from undulate import Checkpoint
    from undulate.errors import ParameterError
    from undulate.params import ControllerParams

    sc = Scene(phases_rad=(0.0, 2.5, 1.0), channel=Channel(width_m=0.2))
    opt = SimOptions(duration_s=4.0, chunk_steps=300)
    stopped = simulate(sc, opt, stop=lambda b: "enough" if float(b[0]["time"][-1]) >= 1.5 else None)
    end = Checkpoint.of(stopped)
    assert end.time_s == pytest.approx(float(stopped["time"][-1]))
    with _walltime.meter() as tally:
        rest = simulate(sc, opt, start=end)
    full = simulate(sc, opt)
    assert float(rest["time"][0]) > end.time_s and rest.sizes["time"] + stopped.sizes["time"] == full.sizes["time"]
    assert tally.steps == full.attrs["physics_steps"] - stopped.attrs["physics_steps"]
    for v in full.data_vars:
        np.testing.assert_array_equal(np.concatenate([stopped[v].values, rest[v].values]), full[v].values, err_msg=v)
    np.testing.assert_array_equal(rest.attrs["end_state"], full.attrs["end_state"])
    assert float(full["contact_force_pair"].max()) > 0.01  # the bodies touched
    off = Checkpoint(end.state.copy(), end.warmstart)
    off.state[0] += 0.01  # between samples
    for bad, sc_, match in [(off, sc, "sample time"), (Checkpoint(end.state[:-1], end.warmstart), sc, "model"),
                            (end, Scene(phases_rad=(0.0, 2.5, 1.0), channel=Channel(width_m=0.2),
                                        controller=ControllerParams(kind="relay")), "open-loop")]:
        with pytest.raises(ParameterError, match=match):
            simulate(sc_, opt, start=bad)


def test_a_batch_with_one_rule_per_scene_stops_each_scene_as_its_run_alone():
    """Per-scene rules in one batch: each scene ends at its own stop and is stepped no further (the
    steps counted are the scenes' own), and each Dataset is bitwise the scene's run alone, closed
    loop included (the controller is vectorised over the batch)."""
    from undulate import simulate_batch
    from undulate.params import ControllerParams

    def stop_at(t_end):
        def stop(blocks):
            return f"at {t_end}" if float(blocks[0]["time"][-1]) >= t_end - 1e-9 else None
        return stop

    p = ControllerParams(kind="relay")
    scenes = [Scene(phases_rad=(0.0, d), channel=Channel(width_m=0.13), controller=p) for d in (0.5, 2.0, -2.5)]
    opt = SimOptions(duration_s=4.0, chunk_steps=300, record=("x", "joint_angle", "contact_force_pair", "gait_phase"))
    ends = (1.0, 4.0, 2.0)
    with _walltime.meter() as tally:
        batch = simulate_batch(scenes, opt, stop=[stop_at(e) for e in ends])
    alone = [simulate(sc, opt, stop=stop_at(e)) for sc, e in zip(scenes, ends)]
    assert tally.steps == sum(a.attrs["physics_steps"] for a in alone) < 3 * alone[1].attrs["physics_steps"]
    for b, a, e in zip(batch, alone, ends):
        assert b.attrs["stopped_at"] == a.attrs["stopped_at"] and b.attrs["stop_reason"] == a.attrs["stop_reason"]
        assert a.attrs["stopped_at"] == pytest.approx(e, abs=0.21)  # the chunk that reaches e
        for v in a.data_vars:
            np.testing.assert_array_equal(b[v].values, a[v].values, err_msg=v)
    assert max(float(a["contact_force_pair"].max()) for a in alone) > 0.01  # the pairs touched
    with pytest.raises(Exception, match="stop"):
        simulate_batch(scenes, opt, stop=[stop_at(1.0)])


@pytest.fixture(scope="module")
def lone():
    ds = lone_swimmer({}, 0)
    return float(ds["amplitude_m"]), float(ds["mean_joint_error_rad"])


@pytest.mark.parametrize("rho, early", [(1.0, True), (6.0, True), (2.35, False)])
def test_packing_probe_stops_only_when_decided(lone, rho, early):
    """Eight swimmers, phi_max = pi: far below (1.0) and far above (6.0) the contact threshold the
    probe stops after its three batches; at 2.35 (excess ~ +0.003 rad) it is not decided and runs on."""
    amp, err = lone
    kw = dict(amplitude_m=amp, base_seed=1, n_swimmers=8, duration_s=8.0)
    point = {"phi_max_rad": math.pi, "rho_tilde": rho, "draw": 0}
    short = packing_point(point, 0, stop=PACKING_STOP, lone_error_rad=err, **kw)
    assert (float(short["stopped_at_s"]) < 8.0 - 1e-9) is early
    full = packing_point(point, 0, **kw)
    side = np.sign(float(full["mean_joint_error_rad"]) - err - THRESHOLD_RAD)
    assert np.sign(float(short["mean_joint_error_rad"]) - err - THRESHOLD_RAD) == side
    assert "ExcessStop(confidence=0.99" in short["stopped_at_s"].attrs["stop_rule"]
    if early:  # a bracket run is continued from its stop: bitwise the run that never stopped
        went_on = packing_continue(point, 0, resume=Resumes({Resumes.key(point): short}), **kw)
        for v in full.data_vars:
            np.testing.assert_array_equal(went_on[v].values, full[v].values, err_msg=v)


def test_excess_rule_needs_its_batches_and_its_confidence():
    rule = ExcessStop(confidence=0.99, min_batches=3)
    assert rule.side([0.1, 0.1]) == 0  # too few batches
    assert rule.side([0.10, 0.11, 0.12]) == 1
    assert rule.side([-0.01, -0.0101, -0.0099]) == -1
    assert rule.side([0.01, -0.01, 0.012]) == 0  # scatter straddles the level


# ---- closed-loop pairs: the phase-lock rule --------------------------------------------------------------
def test_phase_rule_on_closed_forms():
    """Locked: a constant phase difference with jitter inside half the tolerance; not locked: jitter
    beyond that margin, one whose
    trend, carried to the end of the run, moves it by more than half the tolerance (each sample
    within the tolerance of the mean), one that jumps, or a window shorter than hold_s + extra_s."""
    from undulate.stopping import PhaseStop

    rule = PhaseStop(tol_rad=0.15, hold_s=10.0, extra_s=10.0)
    t = np.arange(0.0, 20.0 + 1e-9, 0.05)
    rng = np.random.default_rng(0)
    jitter = 0.05 * np.sin(7 * t)[:, None]
    assert rule.locked(t, np.pi - 0.02 + jitter)  # across the +-pi cut: wrapped
    assert rule.locked(t, np.angle(np.exp(1j * (np.pi + jitter + 0.005 * rng.standard_normal((len(t), 1))))))
    assert not rule.locked(t, 0.1 * np.sin(7 * t)[:, None])  # within tol_rad, not within the margin
    ramp = (0.07 / 10.0) * (t - 10.0)[:, None]  # within 0.07 of the mean, 0.007 rad/s
    assert rule.locked(t, ramp, time_left_s=0.0) and not rule.locked(t, ramp, time_left_s=20.0)
    creep = 0.002 * (t - 10.0)[:, None]  # 0.002 rad/s: 0.08 rad more in 40 s, > 0.075
    assert rule.locked(t, creep, time_left_s=30.0) and not rule.locked(t, creep, time_left_s=40.0)
    assert not rule.locked(t, np.where(t[:, None] < 15.0, 0.0, 0.5))
    assert not rule.locked(t[t <= 19.0], np.zeros((int((t <= 19.0).sum()), 1)))


def test_stopped_sync_pair_is_the_full_runs_prefix_and_gives_its_lock():
    """A held relay-controlled pair that locks: the stopped run ends between 2 TAIL_S and the end, its
    phase series is bitwise the full run's prefix, and its final phase difference, lock time and
    final force agree with the full run's within the lock tolerance / one sample / 10 %."""
    from undulate.studies.synchronization import LOCK_TOL_RAD, PAIR_SYNC_STOP, TAIL_S, pair_run

    point = {"controller": "relay", "hold_x": True, "dphi0_rad": math.pi / 2}
    full = pair_run(point, 0, duration_s=40.0)
    short = pair_run(point, 0, duration_s=40.0, stop=PAIR_SYNC_STOP)
    stop_s = float(short["stopped_at_s"])
    assert 2 * TAIL_S <= stop_s < 40.0 == float(full["stopped_at_s"])
    n = _finite_len(short["dphi"].values)
    np.testing.assert_array_equal(short["time"].values, full["time"].values)
    np.testing.assert_array_equal(short["dphi"].values[:n], full["dphi"].values[:n])
    assert np.isnan(short["dphi"].values[n:]).all()
    assert abs(np.angle(np.exp(1j * (float(short["dphi_final"]) - float(full["dphi_final"]))))) <= LOCK_TOL_RAD
    assert abs(float(short["lock_time"]) - float(full["lock_time"])) <= 0.05 + 1e-9
    assert float(short["force_start"]) == float(full["force_start"])
    assert abs(float(short["force_end"]) - float(full["force_end"])) <= 0.1 * abs(float(full["force_end"])) + 1e-3
    assert "PhaseStop(tol_rad=0.15" in short["stopped_at_s"].attrs["stop_rule"]


def test_potential_reads_the_last_periods_each_force_run_stepped():
    """A force run stopped early is read over its own last 3 periods, a whole run over the end."""
    from undulate.studies.potential import DRIFT, FORCE_STOP, _last_periods

    pm = np.array([[0.0, 1.0, 2.0, 3.0, 4.0, 5.0], [0.0, 1.0, 2.0, 3.0, np.nan, np.nan], [np.nan] * 6])
    got = _last_periods(pm, 3)
    np.testing.assert_array_equal(got[0], [3.0, 4.0, 5.0])
    np.testing.assert_array_equal(got[1], [1.0, 2.0, 3.0])
    assert np.isnan(got[2]).all()
    # the rule's margin: a window it accepts has a range within the study's DRIFT
    assert 2 * FORCE_STOP.spread_frac * FORCE_STOP.tol <= DRIFT
    assert FORCE_STOP.drift_frac * FORCE_STOP.tol <= DRIFT


def test_a_packing_run_that_diverges_is_a_nan_result_of_the_same_shapes(monkeypatch):
    """A diverged probe is stored, not raised: NaN measurements, flagged, with every variable (the
    record and the end state included) shaped as a completed run's, so the sweep's runs merge."""
    import undulate.simulation as sim
    from undulate.errors import DivergenceError

    kw = dict(amplitude_m=0.052, base_seed=1, n_swimmers=4, duration_s=2.5)
    point = {"phi_max_rad": math.pi, "rho_tilde": 3.0, "draw": 0}
    ok = packing_point(point, 0, **kw)

    def blow_up(*a, **k):
        raise DivergenceError("test: diverged")

    monkeypatch.setattr(sim, "simulate", blow_up)
    bad = packing_point(point, 0, **kw)
    assert bool(bad["diverged"]) and not bool(ok["diverged"])
    assert set(bad.data_vars) == set(ok.data_vars)
    for v in ok.data_vars:
        assert bad[v].shape == ok[v].shape, v
    assert np.isnan(float(bad["mean_joint_error_rad"])) and np.isfinite(float(ok["mean_joint_error_rad"]))
    assert np.isnan(bad["end_state"].values).all() and np.isfinite(ok["end_state"].values).all()


def test_the_continued_runs_identity_follows_the_stopped_runs_content():
    """Resumes is bound into the continuing sweep's call: its repr is a hash of the stopped runs'
    records and end states, so a changed stopped run makes the continued ones stale."""
    import xarray as xr

    def run(x):
        return xr.Dataset({"series_time_s": ("sample", [0.0, 0.1, np.nan]),
                           "series_joint_error_rad": ("sample", [0.1, x, np.nan]),
                           "series_wall_force_N": (("sample", "wall"), np.zeros((3, 2))),
                           "series_penetration_m": ("sample", [0.0, 0.0, np.nan]),
                           "end_state": ("state", [0.1, 1.0, 2.0]), "end_warmstart": ("dof", [0.0, 0.5])})

    point = {"phi_max_rad": math.pi, "rho_tilde": 3.0, "draw": 0}
    a, b, c = (Resumes({Resumes.key(point): run(x)}) for x in (0.2, 0.2, 0.3))
    assert repr(a) == repr(b) != repr(c)
    fn = functools.partial(packing_continue, amplitude_m=0.05, base_seed=0)
    assert function_id(functools.partial(fn, resume=a)) != function_id(functools.partial(fn, resume=c))
    sr, end = a.get(point)
    assert len(sr["time"]) == 2 and end.time_s == 0.1  # the record up to the stop, NaN padding dropped


@pytest.mark.slow
def test_xi32_eight_link_pairs_stop_as_the_sensitivity_study_reads_them():
    """The sensitivity study's N = 8, xi = 3/2 pairs run up to 60 s under PAIR_STOP and are cut at 30 s for
    the explanation's 30 s case: both cases give the whole 60 s run's answers (cut at 30 s and whole) within
    the steady tolerance, and the stopped run is that run's bitwise prefix."""
    from undulate.studies._sensitivity_runs import _cut, _pair_rows, _timestep

    dphi = -math.pi / 2
    point = {"dphi_rad": dphi, "waves_per_body": 1.5, "n_links": 8, "timestep_s": _timestep(8)}
    stopped = group_point(point, 0, duration_s=60.0, stop=PAIR_STOP)
    whole = group_point(point, 0, duration_s=60.0)
    assert float(stopped["stopped_at_s"]) < 60.0
    n = _finite_len(stopped["x"].values)
    np.testing.assert_array_equal(stopped["x"].values[:n], whole["x"].values[:n])
    lam, amp = float(whole["wavelength"]), 0.05
    for cut_s in (30.0, 60.0):
        (dx_a, _, steady_a), (dx_b, _, steady_b) = (_pair_rows(_cut(r, cut_s), dphi, lam, amp)[3]
                                                   for r in (stopped, whole))
        assert steady_a == steady_b == 1.0, cut_s
        assert abs(dx_a - dx_b) <= C.STEADY_TOL, cut_s


def test_the_leave_rule_on_constructed_period_means():
    rule = SteadyStop(tol=0.01, window=3, leave=0.45, leave_after_s=6.0)
    before = np.array([0.0, 0.0])
    sliding = np.array([[0.0, 0.5], [0.0, 1.1], [0.0, 1.7]])  # swimmer 1 pulled along x, still moving
    assert rule.left(sliding, before)
    assert not rule.left(sliding[:2], before)  # fewer than `window` periods
    relocked = np.array([[0.0, 1.0], [0.0, 1.002], [0.0, 1.001]])  # far, but no longer moving
    assert not rule.left(relocked, before)
    near = np.array([[0.0, 0.3], [0.0, 0.4], [0.0, 0.5]])  # moving, but one period within 0.45
    assert not rule.left(near, before)
    assert not SteadyStop().left(sliding, before)  # leave = inf: never
    assert "left its state" in rule.rule and "left its state" not in SteadyStop().rule


@pytest.mark.slow
def test_a_force_run_pulled_apart_stops_when_it_has_left_and_reads_broken():
    """Potential's force runs: a pair the force pulls apart (45 deg, d/2A = 0.7, W = 146 mm, 0.3 N: broken
    in full mode) stops once it has left its state, bitwise the prefix of the whole 50 s run, and the study
    reads both as broken; a pair that holds (d/2A = 0.5, W = 105 mm, 0.1 N) stops as before (leaving
    never fires)."""
    from undulate.studies.potential import BREAK, DRIFT, DURATION_S, FORCE_STOP, SETTLE_S, _last_periods

    amp = float(lone_swimmer({"amplitude_rad": math.radians(45)}, 0)["amplitude_m"])
    old = SteadyStop(**{**FORCE_STOP.__dict__, "leave": math.inf})
    run = functools.partial(pair_point, duration_s=DURATION_S, force_onset_s=SETTLE_S)

    def broken(r):
        pm = r["dx_period_over_lambda"].values[None, :]
        k_before = int(np.flatnonzero(r["period_time"].values < SETTLE_S)[-1])
        last = _last_periods(pm, 3)[0]
        return bool(last.mean() - pm[0, k_before] > BREAK or np.ptp(last) > DRIFT)

    pulled = {"amplitude_rad": math.radians(45), "amplitude_m": amp, "d_over_2A": 0.7, "force_N": 0.3}
    new, whole = run(pulled, 0, stop=FORCE_STOP), run(pulled, 0, stop=old)
    assert float(whole["stopped_at_s"]) == DURATION_S and float(new["stopped_at_s"]) <= 30.0
    n = _finite_len(new["dx_over_lambda"].values)
    np.testing.assert_array_equal(new["dx_over_lambda"].values[:n], whole["dx_over_lambda"].values[:n])
    assert broken(new) and broken(whole)
    held = {**pulled, "d_over_2A": 0.5, "force_N": 0.1}
    a, b = run(held, 0, stop=FORCE_STOP), run(held, 0, stop=old)
    assert float(a["stopped_at_s"]) == float(b["stopped_at_s"]) < DURATION_S and not broken(a)
    np.testing.assert_array_equal(a["dx_period_over_lambda"].values, b["dx_period_over_lambda"].values)


@pytest.mark.parametrize("make, message", [
    (lambda: SteadyStop(tol=-0.01), "invalid tol: must be >= 0"),
    (lambda: SteadyStop(window=0), "invalid window: must be an integer >= 1"),
    (lambda: SteadyStop(extra_periods=1.5), "invalid extra_periods: must be an integer >= 0"),
    (lambda: SteadyStop(leave=0.0), "invalid leave: must be > 0"),
    (lambda: PhaseStop(tol_rad=0.0), "invalid tol_rad: must be > 0 rad"),
    (lambda: PhaseStop(hold_s=float("nan")), "invalid hold_s: must be a finite number"),
    (lambda: PhaseStop(steady=0.01), "invalid steady: must be a SteadyStop"),
    (lambda: ExcessStop(confidence=1.0), "invalid confidence: must be a level in (0, 1)"),
    (lambda: ExcessStop(min_batches=0), "invalid min_batches: must be an integer >= 1"),
])
def test_stopping_rules_refuse_settings_that_cannot_stop_a_run_honestly(make, message):
    """A rule with a window of no periods, a negative tolerance or a confidence of 1 is refused when it
    is made, naming the setting (before, SteadyStop(window=0) was accepted and failed inside a run, and
    PhaseStop(tol_rad=-1) could never stop one)."""
    from undulate.errors import ParameterError

    with pytest.raises(ParameterError) as err:
        make()
    assert message in str(err.value)
    assert SteadyStop(leave=math.inf).leave == math.inf  # inf: never leave
