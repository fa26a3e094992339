"""The resistive-force medium (``Ground(mode="resistive")``): viscous swimming by resistive-force
theory, linear drag per link along and across its own axis, computed by MuJoCo each step.

Physics asserted: the drag on a link moving at a known velocity is the closed form (along, across,
about the normal); with ``c_perp = c_par`` a swimmer makes no net progress (the total drag is then
``-c N v_com``: nothing can propel the centre of mass); with ``c_perp > c_par`` it swims head first
(-x), faster with more anisotropy, at the speed an independent inertialess RFT integration of the
same kinematics gives; the drag is integrated implicitly (stable where an explicit step diverges).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from undulate import Channel, Ground, Scene, SimOptions
from undulate.errors import ParameterError
from undulate.scene import build, resistive_coefficients
from undulate.simulation import simulate

LONE = dict(phases_rad=(0.0,), channel=Channel(width_m=1.0))
PERIODS = 4


def _lone(anisotropy: float = 2.0, c_par: float = 2.0) -> Scene:
    return Scene(**LONE, ground=Ground.resistive(drag_N_s_per_m=c_par, drag_anisotropy=anisotropy))


def _period_centres(scene: Scene, periods: int = PERIODS) -> np.ndarray:
    """The centre of mass averaged over each gait period, (periods, 2) m."""
    T = scene.gait.period_s
    ds = simulate(scene, SimOptions(duration_s=periods * T, sample_rate_hz=50.0))
    t, x, y = ds["time"].values, ds["x"].values[:, 0], ds["y"].values[:, 0]
    return np.array([[x[(t >= k * T) & (t < (k + 1) * T)].mean(), y[(t >= k * T) & (t < (k + 1) * T)].mean()]
                     for k in range(periods)])


def _steady_step(scene: Scene) -> np.ndarray:
    """Displacement of the period-averaged centre over the last period, m (2-vector)."""
    c = _period_centres(scene)
    return c[-1] - c[-2]


def test_validation():
    with pytest.raises(ParameterError, match="drag_anisotropy"):
        Ground(mode="resistive", drag_anisotropy=0.5)
    with pytest.raises(ParameterError, match="drag_anisotropy"):
        Ground(mode="resistive", drag_anisotropy=math.nan)
    with pytest.raises(ParameterError, match="drag_N_s_per_m"):
        Ground.resistive(drag_N_s_per_m=0.0)
    with pytest.raises(ParameterError, match="mode"):
        Ground(mode="rft")
    g = Ground.resistive()
    assert (g.mode, g.drag_N_s_per_m, g.drag_anisotropy, g.normal_drag_N_s_per_m) == ("resistive", 2.0, 2.0, 4.0)
    assert Ground(mode="resistive", drag_anisotropy=1.0).normal_drag_N_s_per_m == 2.0  # 1 is allowed: isotropic


def test_drag_on_each_link_is_the_closed_form():
    """Any state: each link feels -c_par v_par, -c_perp v_perp and -c_perp l^2/12 omega, where the
    velocities are the link centre's, in the link's own frame (from MuJoCo's object velocity, not from
    the actuators), whatever the control inputs; the generalised force is that wrench at the centre."""
    sc = _lone(anisotropy=3.0, c_par=1.5)
    m = build(sc).model
    assert m.opt.viscosity == 0.0 and m.opt.density == 0.0  # the drag actuators are the whole medium
    c_par, c_perp, c_rot = resistive_coefficients(sc)
    l = sc.geometry.link_length_m
    assert (c_par, c_perp) == (1.5, 4.5) and c_rot == pytest.approx(4.5 * l * l / 12)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(3)
    d.qpos[:] = rng.normal(size=m.nq) * 0.4
    d.qvel[:] = rng.normal(size=m.nv) * 0.3
    d.ctrl[:] = rng.normal(size=m.nu)  # the drag ignores its inputs (gain 0)
    mujoco.mj_forward(m, d)
    drag_ids = []
    qfrc = np.zeros(m.nv)
    for k in range(sc.geometry.n_links):
        sid = m.site(f"s0_c{k}").id
        v6 = np.zeros(6)  # (angular, linear) in the site's frame
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_SITE, sid, v6, 1)
        want = {"par": -c_par * v6[3], "perp": -c_perp * v6[4], "rot": -c_rot * v6[2]}
        for axis, f in want.items():
            a = m.actuator(f"s0_drag{k}_{axis}").id
            drag_ids.append(a)
            assert d.actuator_force[a] == pytest.approx(f, rel=1e-12, abs=1e-15)
        assert abs(v6[3]) > 1e-3 and abs(v6[4]) > 1e-3 and abs(v6[2]) > 1e-3  # every term is exercised
        # the same wrench applied by hand at the link centre, in world axes
        R = d.site_xmat[sid].reshape(3, 3)
        force = R @ np.array([want["par"], want["perp"], 0.0])
        torque = R @ np.array([0.0, 0.0, want["rot"]])
        jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        mujoco.mj_jacSite(m, d, jp, jr, sid)
        qfrc += jp.T @ force + jr.T @ torque
    servo = [m.actuator(f"s0_servo{i}").id for i in range(sc.geometry.n_links - 1)]
    moment = np.zeros((m.nactuator, m.nv))
    mujoco.mju_sparse2dense(moment, d.actuator_moment, d.moment_rownnz, d.moment_rowadr, d.moment_colind)
    drag_qfrc = moment[drag_ids].T @ d.actuator_force[drag_ids]
    np.testing.assert_allclose(drag_qfrc, qfrc, rtol=1e-10, atol=1e-14)
    assert len(servo) + len(drag_ids) == m.nactuator


def test_isotropic_drag_makes_no_net_progress():
    """c_perp = c_par: the total drag is -c N v_com, so from rest the centre of mass cannot move.  What is
    left is the first-order integrator's position creep; it is bounded by a thousandth of what the same
    swimmer covers per period at c_perp = 2 c_par (measured: ~1e-6 m against 1.46e-2 m)."""
    still = np.linalg.norm(_steady_step(_lone(anisotropy=1.0)))
    swims = np.linalg.norm(_steady_step(_lone(anisotropy=2.0)))
    assert swims > 0.01
    assert still < 1e-3 * swims


def test_anisotropic_drag_swims_head_first_and_faster_with_anisotropy():
    """Heads point to -x: c_perp > c_par drives the swimmer toward -x, and the distance per period
    grows with c_perp / c_par."""
    steps = {a: _steady_step(_lone(anisotropy=a)) for a in (1.5, 2.0, 3.0)}
    for a, s in steps.items():
        assert s[0] < 0 and abs(s[0]) > 10 * abs(s[1]), (a, s)  # head first, along the body
    d = [np.linalg.norm(steps[a]) for a in (1.5, 2.0, 3.0)]
    assert d[0] < d[1] < d[2]


def _rft_step(scene: Scene, dt: float = 4e-3) -> float:
    """Distance per period of an inertialess resistive-force swimmer with the commanded gait: at each
    instant the rigid-body velocity (head point, heading) is the one that makes total drag force and
    torque zero for the given joint motion; RK4 over one period (the inertialess swimmer is periodic from
    the first period).  Independent of MuJoCo: numpy only."""
    g, n, l = scene.gait, scene.geometry.n_links, scene.geometry.link_length_m
    c_par, c_perp, c_rot = resistive_coefficients(scene)

    def rates(q, t):
        a = g.joint_angles(np.array([t]), (0.0,), n)[0, 0]
        ad = g.joint_velocities(np.array([t]), (0.0,), n)[0, 0]
        th = q[2] + np.concatenate([[0.0], np.cumsum(a)])  # link k's angle (head -> tail direction)
        thd = np.concatenate([[0.0], np.cumsum(ad)])
        tv = np.stack([np.cos(th), np.sin(th)], 1)
        nv = np.stack([-np.sin(th), np.cos(th)], 1)
        r = np.concatenate([[[0.0, 0.0]], np.cumsum(l * tv, 0)[:-1]]) + 0.5 * l * tv  # centres from the head
        A, b = np.zeros((3, 3)), np.zeros(3)
        for k in range(n):
            w = [l * nv[i] for i in range(k)] + [0.5 * l * nv[k]]  # d r_k / d th_i
            J = np.column_stack([[1.0, 0.0], [0.0, 1.0], np.sum(w, 0)])
            s = np.sum([thd[i] * w[i] for i in range(k + 1)], 0)
            D = c_par * np.outer(tv[k], tv[k]) + c_perp * np.outer(nv[k], nv[k])
            FJ, Fs = -D @ J, -D @ s
            A[:2] += FJ
            b[:2] += Fs
            A[2] += r[k, 0] * FJ[1] - r[k, 1] * FJ[0]
            A[2, 2] -= c_rot
            b[2] += r[k, 0] * Fs[1] - r[k, 1] * Fs[0] - c_rot * thd[k]
        return np.linalg.solve(A, -b), r.mean(0)

    T = g.period_s
    q, com = np.zeros(3), []
    ts = np.arange(0.0, T, dt)
    for t in ts:
        k1, c = rates(q, t)
        com.append(q[:2] + c)
        k2 = rates(q + dt / 2 * k1, t + dt / 2)[0]
        k3 = rates(q + dt / 2 * k2, t + dt / 2)[0]
        k4 = rates(q + dt * k3, t + dt)[0]
        q = q + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    # the rigid motion over a period is the same every period; the centre's displacement over a period
    # equals the head point's (the shape repeats): rotate back by the net turn (zero for this gait)
    assert abs(q[2]) < 1e-9
    return float(np.hypot(q[0], q[1]))


@pytest.mark.parametrize("anisotropy", [2.0, 3.0])
def test_lone_speed_matches_an_independent_rft_integration(anisotropy):
    """The simulated swimmer (mass, servo tracking) against inertialess RFT of the commanded gait, within
    2 %: the link's drag relaxation time m / c_perp = 25 ms is 1.3 % of the period and the servos track
    to ~0.006 rad of 0.68 rad (measured agreement: 0.1-0.2 %)."""
    sc = _lone(anisotropy=anisotropy)
    sim = np.linalg.norm(_steady_step(sc))
    assert sim == pytest.approx(_rft_step(sc), rel=0.02)


def test_drag_is_implicit_where_an_explicit_step_diverges():
    """c_par = 200 N s/m: the link's relaxation time m / c_perp = 0.25 ms is below the 2 ms step, so an
    explicit (Euler) step diverges; implicitfast, with the drag in qDeriv, decays."""
    sc = _lone(c_par=200.0)
    for integrator, stable in ((mujoco.mjtIntegrator.mjINT_IMPLICITFAST, True), (mujoco.mjtIntegrator.mjINT_EULER, False)):
        m = build(sc).model
        assert m.opt.timestep == pytest.approx(0.002)
        m.opt.integrator = integrator
        d = mujoco.MjData(m)
        d.qvel[:] = 0.1
        for _ in range(200):
            mujoco.mj_step(m, d)
        diverged = d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0
        assert diverged != stable
        if stable:
            assert np.abs(d.qvel).max() < 1e-3


def test_drag_inputs_leave_servo_push_and_guide_inputs_alone():
    """The drag actuators are found by name and get control 0: a pair with a push force and the heading
    guide gets the same servo, push and guide controls as on the viscous ground (each column resolved by
    name in its own model), and 0 in every drag input."""
    kw = dict(phases_rad=(0.0, 1.0), forces_N=(-0.1, 0.1), heading_guide=True)
    rv, vv = build(Scene(**kw, ground=Ground.resistive())), build(Scene(**kw))
    assert rv.model.nu == vv.model.nu + 2 * 3 * 3
    t = np.linspace(0, 2, 11)
    u_r, u_v = rv.controls(t), vv.controls(t)
    used = []
    for f in ("ctrl_pos", "ctrl_vel", "ctrl_push", "ctrl_heading"):
        np.testing.assert_array_equal(u_r[:, getattr(rv.index, f)], u_v[:, getattr(vv.index, f)])
        used += list(np.ravel(getattr(rv.index, f)))
    drag = [int(rv.model.actuator_ctrladr[rv.model.actuator(f"s{j}_drag{k}_{a}").id])
            for j in range(2) for k in range(3) for a in ("par", "perp", "rot")]
    assert sorted(set(used) | set(drag)) == list(range(rv.model.nu))
    assert not u_r[:, drag].any() and np.abs(u_v).max() > 0


@pytest.mark.slow
def test_warp_steps_the_resistive_medium(monkeypatch):
    """MuJoCo Warp (its CPU device) steps the same drag actuators: a lone resistive swimmer agrees with
    the MuJoCo backend to 1e-6 m over one period (float32; measured 2e-8 m)."""
    pytest.importorskip("warp")
    pytest.importorskip("mujoco_warp")
    monkeypatch.setenv("UNDULATE_WARP_LONE_SWIMMERS", "warp")
    sc = _lone()
    o = dict(duration_s=2.0, sample_rate_hz=50.0)
    w = simulate(sc, SimOptions(**o, backend="warp", device="cpu"))
    m = simulate(sc, SimOptions(**o))
    assert w.attrs["backend"] == "warp"
    np.testing.assert_allclose(w["x"].values, m["x"].values, atol=1e-6)
    np.testing.assert_allclose(w["y"].values, m["y"].values, atol=1e-6)


def test_study_points_name_the_resistive_ground():
    """Sweep points: ``ground="resistive"`` is :meth:`Ground.resistive`, with ``drag_N_s_per_m`` (if given)
    its tangential coefficient; an unknown ground is refused naming the allowed ones."""
    from undulate.studies._points import LonePoint, PairPoint
    from undulate.studies._runners import pair_scene

    assert LonePoint.of({"ground": "resistive"}).ground_model() == Ground.resistive()
    assert pair_scene({"ground": "resistive"}).ground == Ground.resistive()
    assert pair_scene({"ground": "resistive", "drag_N_s_per_m": 1.0}).ground == Ground.resistive(drag_N_s_per_m=1.0)
    with pytest.raises(ParameterError, match="resistive"):
        PairPoint.of({"ground": "rft"})
