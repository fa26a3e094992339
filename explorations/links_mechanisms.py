"""Candidate causes of the links claim's failure (exploratory; measured, never asserted).

    python explorations/links_mechanisms.py wavelength   # ~1 min on 2 cores
    python explorations/links_mechanisms.py attractor    # ~15 s
    python explorations/links_mechanisms.py recoil       # ~20 s
    python explorations/links_mechanisms.py yaw-guided   # ~20 s
    python explorations/links_mechanisms.py smooth-limit # ~20 s
    python explorations/links_mechanisms.py quasi-static # ~45 s
    python explorations/links_mechanisms.py waves        # ~2 min
    python explorations/links_mechanisms.py inertia      # ~1.5 min
    python explorations/links_mechanisms.py held-force   # ~10 s
    python explorations/links_mechanisms.py recoil-free  # ~1.5 min

Pairs of N = 3, 5, 7, 9 links, xi = 1, d = 0.13 m, the paper's nine dphi, 30 s
from dx0 = 0 at the simulator's time step (the links study's set-up).

* ``wavelength``: for the links study's two rules and the sensitivity study's
  equal-A rule, the in-pair head-to-tail extent along x per wave, lambda_x
  (time mean over t >= 20 s, both swimmers), and the RMS distance from the
  nearest compatibility branch with lambda = L (the report's) and with
  lambda = lambda_x (the wavelength along the channel, the one a lab-frame
  sinusoid y = A sin(2 pi x / lambda - omega t) has).
* ``attractor``: equal-A pairs run 90 s from dx0 = 0 and from beyond the
  line: dx / L averaged over 5 s windows (is the steady offset one stable
  point or the near edge of a band?).
* ``recoil``: the free equal-A swimmer's yaw recoil (head-to-tail chord angle
  amplitude) and the kinematically compatible offset of its lab-frame shapes:
  the dx that minimises the spread (max - min over x and a period) of the
  lateral gap between a shape and the same shape delayed by dphi / omega;
  then the same with the recoil rotated out (chord along x).
* ``yaw-guided``: equal-A pairs (the free body's beta) whose yaw recoil is
  removed (``Scene.heading_guide``: a stiff PD actuator on the root yaw holds
  the commanded shape's chord along x).  The guided body's A is then smaller
  (41 mm at N = 9), so the confinement changes too: see ``recoil-free``.
* ``smooth-limit``: N = 9, 13, 17 at (near) equal A, three dphi: does the
  offset converge as the body gets smoother, and to what?
* ``quasi-static``: N = 3 and 9 at three dphi with one model choice changed
  at a time (frequency, drag, contact softness, link height, mass, collision
  shape, link width at the same clearance).
* ``waves``: bodies of 2 and 3 waves (xi), each wave of N = 3 ... 9 links of
  the usual size (length and mass scale with xi): is it the finite body?
* ``inertia``: the three amplitude rules with 3x and 10x the body mass.
* ``held-force``: pairs with x held at dx0 (``Scene.hold_x``): the
  cycle-mean longitudinal contact force and the link pairs that carry it
  (a diagnostic that steps MuJoCo from Python to read every contact).
* ``recoil-free``: the cause.  The free body's lateral excursion along it
  with and without the heading guide; then pairs with the recoil removed at
  the guided A equal to the 3-link body's (only the guide and beta changed),
  the residual taken with lambda = L and with the measured lambda_x (the
  head-to-tail extent along x); and the same with 4x servo stiffness and
  torque.  The sensitivity study runs the default-servo part.

Results: docs/claims_explained.md (links).
"""

from __future__ import annotations

import math
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from undulate import theory
from undulate.params import Channel, Gait, Scene, SimOptions, SwimmerGeometry
from undulate.simulation import simulate
from undulate.studies import _analysis as C
from undulate.studies._gaits import equal_amplitude_beta
from undulate.studies._runners import lone_swimmer
from undulate.studies.links import joint_amplitude, timestep

L_M = 0.54
EQUAL_A_DEG = {3: 45.0, 5: 30.860722776778964, 7: 22.742857116869637, 9: 17.846897234093458}
"""The sensitivity study's equal-A joint amplitudes (free swimmer's A = 52.3 mm at every N)."""
N_LINKS = (3, 5, 7, 9)


def _beta(rule: str, n: int) -> float:
    return math.radians(EQUAL_A_DEG[n]) if rule == "equal-A" else joint_amplitude(rule, n)


def _pair_scene(n, beta, dphi, dx0_over_L=0.0, *, xi=1.0, frequency_hz=0.5, width_m=0.13, geometry=None,
                ground=None, contact=None, hold_x=False, heading_guide=False, servo=None):
    """The links study's pair, with one model choice changed (``geometry``: SwimmerGeometry overrides;
    ``xi`` > 1 scales the body length and mass with xi, so each wave keeps N links of the same size)."""
    g = dict(n_links=int(round(n * xi)), length_m=L_M * xi, mass_kg=0.3 * xi) | (geometry or {})
    extra = {k: v for k, v in (("ground", ground), ("contact", contact), ("servo", servo)) if v is not None}
    return Scene(phases_rad=(0.0, dphi), gait=Gait(amplitude_rad=beta, waves_per_body=xi, frequency_hz=frequency_hz),
                 dx0_m=dx0_over_L * L_M, geometry=SwimmerGeometry(**g), channel=Channel(width_m=width_m),
                 hold_x=hold_x, heading_guide=heading_guide, **extra)


def _pair(n, beta, dphi, duration_s=30.0, dx0_over_L=0.0, record=("x", "y"), **change):
    """Run :func:`_pair_scene` at the links study's time step for N (per wave) and 50 samples per second."""
    sc = _pair_scene(n, beta, dphi, dx0_over_L, **change)
    return simulate(sc, SimOptions(duration_s=duration_s, timestep_s=timestep(n), sample_rate_hz=50, record=record))


def _steady_dx(ds):
    """(steady dx_upper - dx_lower over L, dphi_upper - dphi_lower): the studies' neighbour order and
    steady-state rule (:mod:`undulate.studies._analysis`)."""
    traj = C.trajectory(ds, L_M, float(ds.attrs["period"]))
    (lower, upper), = C.final_neighbours(traj)[0]
    dx, dy, dphi = C.neighbour_series(traj, lower, upper)
    return C.steady_offsets(dx, dy, L_M).dx_m / L_M, dphi


def _wavelength_run(args):
    rule, n, dphi = args
    ds = _pair(n, _beta(rule, n), dphi, record=("x", "y", "node_x"))
    late = ds["time"].values >= 20.0
    nx = ds["node_x"].values[late]
    lx = float(np.abs(nx[..., -1] - nx[..., 0]).mean())
    dx, dph = _steady_dx(ds)
    return rule, n, dph, dx, lx


def wavelength():
    jobs = [(r, n, float(d)) for r in ("fixed", "curvature", "equal-A") for n in N_LINKS for d in C.paper_phases()]
    with ProcessPoolExecutor(2) as ex:
        res = list(ex.map(_wavelength_run, jobs))
    for rule in ("fixed", "curvature", "equal-A"):
        for n in N_LINKS:
            rows = [r for r in res if r[0] == rule and r[1] == n]
            dph, dx, lx = (np.array([r[k] for r in rows]) for k in (2, 3, 4))
            lam_x = lx.mean()
            r_L = C.rms(theory.compatibility_residual(dx * L_M, dph, L_M) / L_M)
            r_x = C.rms(theory.compatibility_residual(dx * L_M, dph, lam_x) / lam_x)
            print(f"{rule:9s} N={n}: lambda_x/L {lam_x / L_M:.3f} ({lx.min() / L_M:.3f}-{lx.max() / L_M:.3f}); "
                  f"RMS with L {r_L.value:.3f} [{r_L.low:.3f}, {r_L.high:.3f}], with lambda_x {r_x.value:.3f} "
                  f"[{r_x.low:.3f}, {r_x.high:.3f}]", flush=True)


def _attractor_run(args):
    n, dphi, dx0 = args
    ds = _pair(n, _beta("equal-A", n), dphi, duration_s=90.0, dx0_over_L=dx0)
    t, x = ds["time"].values, ds["x"].values
    dx = (x[:, 1] - x[:, 0]) / L_M
    return args, [float(dx[(t >= a) & (t < a + 5)].mean()) for a in range(0, 90, 5)]


def attractor():
    jobs = [(n, d, x0) for n in (3, 9) for d, starts in ((math.pi / 2, (0.0, 0.45)), (math.pi / 4, (0.0, 0.3)))
            for x0 in starts]
    with ProcessPoolExecutor(2) as ex:
        for (n, d, x0), v in ex.map(_attractor_run, jobs):
            print(f"N={n} dphi={d / math.pi:.2f} pi dx0={x0:.2f} L: dx/L per 5 s " + " ".join(f"{q:.3f}" for q in v),
                  flush=True)


def _free_shapes(n, beta=None, guide=False):
    """One period of a free swimmer's node positions (400 samples): equal-A beta unless given;
    ``guide``: ``Scene.heading_guide``."""
    sc = Scene(phases_rad=(0.0,), gait=Gait(amplitude_rad=_beta("equal-A", n) if beta is None else beta),
               geometry=SwimmerGeometry(n_links=n, length_m=L_M), channel=Channel(width_m=0.5), heading_guide=guide)
    period = sc.gait.period_s
    ds = simulate(sc, SimOptions(duration_s=6 * period, timestep_s=timestep(n), sample_rate_hz=400 / period,
                                 record=("x", "node_x", "node_y")))
    last = ds["time"].values >= 5 * period - 1e-9
    return ds["node_x"].values[last, 0][:-1], ds["node_y"].values[last, 0][:-1]  # one period, 400 samples


def _chord_along_x(nx, ny):
    cx, cy = nx.mean(axis=1, keepdims=True), ny.mean(axis=1, keepdims=True)
    a = np.arctan2(ny[:, 0] - ny[:, -1], nx[:, 0] - nx[:, -1]) - np.pi  # tail -> head chord; head toward -x
    c, s = np.cos(-a)[:, None], np.sin(-a)[:, None]
    return cx + c * (nx - cx) - s * (ny - cy), cy + s * (nx - cx) + c * (ny - cy)


def _profile(nx, ny, xs):
    out = np.empty((nx.shape[0], xs.size))
    for k in range(nx.shape[0]):
        o = np.argsort(nx[k])
        out[k] = np.interp(xs, nx[k][o], ny[k][o], left=np.nan, right=np.nan)
    return out


def _compatible_dx(nx, ny, dphi):
    shift = int(round(dphi / (2 * np.pi) * nx.shape[0]))  # B(t) = A(t - dphi / omega)
    xs = np.linspace(nx.min(), nx.max(), 400)
    ya = _profile(nx, ny, xs)
    grid = np.linspace(-0.1, 0.5, 241) * L_M
    spread = []
    for dx in grid:
        g = _profile(np.roll(nx, shift, axis=0) + dx, np.roll(ny, shift, axis=0), xs) - ya
        spread.append(np.nanmax(g) - np.nanmin(g))
    return grid[int(np.argmin(spread))] / L_M


def recoil():
    for n in N_LINKS:
        nx, ny = _free_shapes(n)
        chord = np.unwrap(np.arctan2(ny[:, -1] - ny[:, 0], nx[:, -1] - nx[:, 0]))
        rx, ry = _chord_along_x(nx, ny)
        phases = (np.pi / 4, np.pi / 2, 3 * np.pi / 4)
        lab = [_compatible_dx(nx, ny, d) for d in phases]
        straight = [_compatible_dx(rx, ry, d) for d in phases]
        print(f"N={n}: chord recoil {(chord.max() - chord.min()) / 2:.3f} rad; compatible dx/L at dphi = pi/4, pi/2, "
              f"3pi/4: lab-frame shapes " + " ".join(f"{v:.3f}" for v in lab)
              + "; recoil rotated out " + " ".join(f"{v:.3f}" for v in straight), flush=True)


def _guided_run(args):
    n, dphi = args
    ds = _pair(n, _beta("equal-A", n), dphi, heading_guide=True)
    return (n,) + _steady_dx(ds)


def yaw_guided():
    with ProcessPoolExecutor(2) as ex:
        res = list(ex.map(_guided_run, [(n, float(d)) for n in N_LINKS for d in C.paper_phases()]))
    for n in N_LINKS:
        print(f"yaw guided N={n}: " + _rms_line([r[1:] for r in res if r[0] == n]), flush=True)


# --- the smooth-body limit, the quasi-static screen, more waves per body, inertia, held-dx forces -----------

SMOOTH_BETA_DEG = {9: EQUAL_A_DEG[9], 13: 12.4, 17: 9.5}
"""N = 13 and 17: joint amplitudes near the equal-A value (not iterated; the free A is printed)."""
THREE_DPHI = (math.pi / 4, math.pi / 2, 3 * math.pi / 4)


def _smooth_run(args):
    n, dphi = args
    beta = math.radians(SMOOTH_BETA_DEG[n])
    if dphi is None:  # the free swimmer's A, the package's one definition (studies._runners.lone_swimmer)
        return args, float(lone_swimmer({"amplitude_rad": beta, "n_links": n}, 0)["amplitude_m"])
    return args, _steady_dx(_pair(n, beta, dphi))[0]


def smooth_limit():
    jobs = [(n, d) for n in SMOOTH_BETA_DEG for d in (None,) + THREE_DPHI]
    with ProcessPoolExecutor(2) as ex:
        res = dict(ex.map(_smooth_run, jobs))
    for n, b in SMOOTH_BETA_DEG.items():
        print(f"N={n} beta {b:.1f} deg, free A {res[(n, None)] * 1e3:.1f} mm: dx/L at dphi = pi/4, pi/2, 3pi/4: "
              + " ".join(f"{res[(n, d)]:.3f}" for d in THREE_DPHI) + " (line 0.125 0.250 0.375)", flush=True)


def _variants():
    from undulate.params import ContactModel, Ground

    return {
        "default": {},
        "frequency 0.125 Hz": {"frequency_hz": 0.125}, "frequency 0.25 Hz": {"frequency_hz": 0.25},
        "frequency 1 Hz": {"frequency_hz": 1.0},
        "drag x1/3 (0.67 N s/m per link)": {"ground": Ground(drag_N_s_per_m=2 / 3)},
        "drag x3 (6 N s/m per link)": {"ground": Ground(drag_N_s_per_m=6.0)},
        "contact time constant 10 ms": {"contact": ContactModel(timeconst_s=0.01)},
        "link height 5 mm (rotational drag)": {"geometry": {"height_m": 0.005}},
        "link height 150 mm": {"geometry": {"height_m": 0.15}},
        "mass x0.1": {"geometry": {"mass_kg": 0.03}}, "mass x10": {"geometry": {"mass_kg": 3.0}},
        "box collision": {"geometry": {"collision_shape": "box"}},
        "width 3 mm, d = 0.106 m (same clearance)": {"geometry": {"width_m": 0.003}, "width_m": 0.106},
    }


def _variant_run(args):
    n, name, dphi = args
    change = _variants()[name]
    dur = 15.0 / change.get("frequency_hz", 0.5)
    return args, _steady_dx(_pair(n, _beta("equal-A", n), dphi, duration_s=dur, **change))[0]


def quasi_static():
    names = list(_variants())
    jobs = [(n, k, d) for k in names for n in (3, 9) for d in THREE_DPHI]
    with ProcessPoolExecutor(2) as ex:
        res = dict(ex.map(_variant_run, jobs))
    for k in names:
        for n in (3, 9):
            print(f"{k:42s} N={n}: dx/L at dphi = pi/4, pi/2, 3pi/4: " + " ".join(f"{res[(n, k, d)]:.3f}" for d in THREE_DPHI)
                  + " (line 0.125 0.250 0.375)", flush=True)


def _rms_line(rows):
    dx, dph = np.array([r[0] for r in rows]), np.array([r[1] for r in rows])
    r = C.rms(theory.compatibility_residual(dx, dph, 1.0))
    return f"RMS {r.value:.3f} [{r.low:.3f}, {r.high:.3f}] lambda; dx/lambda " + " ".join(f"{v:+.3f}" for v in dx)


def _waves_run(args):
    xi, n, dphi = args
    return args, _steady_dx(_pair(n, _beta("equal-A", n), dphi, xi=xi))


def waves():
    jobs = [(xi, n, float(d)) for xi in (2.0, 3.0) for n in N_LINKS for d in C.paper_phases()]
    with ProcessPoolExecutor(2) as ex:
        res = list(ex.map(_waves_run, jobs))
    for xi in (2.0, 3.0):
        for n in N_LINKS:
            print(f"xi={xi:g}, {n} links per wave ({int(n * xi)} links): "
                  + _rms_line([r[1] for r in res if r[0][:2] == (xi, n)]), flush=True)


def _inertia_run(args):
    rule, mass, n, dphi = args
    return args, _steady_dx(_pair(n, _beta(rule, n), dphi, geometry={"mass_kg": mass}))


def inertia():
    jobs = [(r, m, n, float(d)) for r in ("equal-A", "fixed", "curvature") for m in (0.9, 3.0) for n in N_LINKS
            for d in C.paper_phases()]
    with ProcessPoolExecutor(2) as ex:
        res = list(ex.map(_inertia_run, jobs))
    for rule in ("equal-A", "fixed", "curvature"):
        for m in (0.9, 3.0):
            for n in N_LINKS:
                print(f"{rule:9s} mass {m:.1f} kg N={n}: " + _rms_line([r[1] for r in res if r[0][:3] == (rule, m, n)]),
                      flush=True)


def _held_force_run(args):
    """A pair with its x held at dx0: the cycle-mean x-force on swimmer 1 from swimmer 0 over periods 16-20,
    by link of each.  Diagnostic only: the 16 settling periods run in C (``mujoco.rollout``), the 4
    measured ones step in Python to read every contact (not how the package simulates)."""
    import re

    import mujoco
    from mujoco import rollout

    from undulate.scene import build

    n, dphi, dx0 = args
    sc = _pair_scene(n, _beta("equal-A", n), dphi, dx0, hold_x=True)
    dt = timestep(n)
    cs = build(sc, dt)
    m, d = cs.model, mujoco.MjData(cs.model)
    sw, lk = np.full(m.ngeom, -1), np.full(m.ngeom, -1)
    for g in range(m.ngeom):
        r = re.match(r"s(\d+)_?link(\d+)", m.body(m.geom_bodyid[g]).name)
        if r:
            sw[g], lk[g] = int(r.group(1)), int(r.group(2))
    T = sc.gait.period_s
    steps, start = int(round(20 * T / dt)), int(round(16 * T / dt))
    u = cs.controls(np.arange(steps) * dt)  # the open-loop controls of every step, once
    kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(m, kind))
    mujoco.mj_getState(m, d, state, kind)
    for k0 in range(0, start, 20000):  # the 16 settling periods in C, in chunks (memory)
        state = rollout.rollout(m, d, state, u[k0:min(k0 + 20000, start)])[0][0, -1]
    mujoco.mj_setState(m, d, state, kind)
    F, f6 = np.zeros((n, n)), np.zeros(6)
    for k in range(start, steps):  # the 4 measured periods: every contact of every step
        d.ctrl[:] = u[k]
        mujoco.mj_step(m, d)
        for c in range(d.ncon):
            con = d.contact[c]
            a, b = con.geom1, con.geom2
            if sw[a] < 0 or sw[b] < 0 or sw[a] == sw[b]:
                continue
            mujoco.mj_contactForce(m, d, c, f6)
            fx = (con.frame.reshape(3, 3).T @ f6[:3])[0]  # on geom2's body, world x
            i1, i0, fx = (lk[b], lk[a], fx) if sw[b] == 1 else (lk[a], lk[b], -fx)
            F[i1, i0] += fx
    return args, F / (steps - start)


def held_force():
    jobs = [(n, math.pi / 2, x0) for n in (3, 9) for x0 in (0.15, 0.2, 0.25, 0.3)]
    with ProcessPoolExecutor(2) as ex:
        for (n, _, x0), F in ex.map(_held_force_run, jobs):
            top = sorted(((abs(F[i, j]), i, j) for i in range(n) for j in range(n) if F[i, j]), reverse=True)[:3]
            print(f"N={n} dphi=pi/2, dx held at {x0:.2f} L: cycle-mean x-force on swimmer 1 {F.sum() * 1e3:+.1f} mN; "
                  "largest (swimmer-1 link, swimmer-0 link, mN): "
                  + ", ".join(f"({i}, {j}, {F[i, j] * 1e3:+.1f})" for _, i, j in top), flush=True)


# --- the cause: yaw recoil (Scene.heading_guide) and the wavelength along the channel ---------------------

def _free_envelope(n, beta, guide):
    """A free swimmer's lateral excursion (half range of y over one period) at each node, m, and
    its head-to-tail chord's swing, rad."""
    nx, ny = _free_shapes(n, beta, guide)
    chord = np.arctan2(ny[:, -1] - ny[:, 0], nx[:, -1] - nx[:, 0])
    return (ny.max(0) - ny.min(0)) / 2, (chord.max() - chord.min()) / 2


def _guided_beta(n):
    """(beta, A): the joint amplitude at which the guided free swimmer's A is the 3-link free swimmer's,
    by the sensitivity study's own secant (:func:`undulate.studies._gaits.equal_amplitude_beta`), here on
    uncached free-swimmer runs (:func:`undulate.studies._runners.lone_swimmer`)."""
    def amplitude_m(beta):
        point = {"amplitude_rad": beta, "n_links": n, "waves_per_body": 1.0, "heading_guide": True}
        return float(lone_swimmer(point, 0)["amplitude_m"])

    return equal_amplitude_beta(amplitude_m, n, float(lone_swimmer({}, 0)["amplitude_m"]))


def _recoil_free_run(args):
    n, beta, dphi, servo_x = args
    from undulate.params import Servo

    sv = Servo(kp_Nm_per_rad=Servo().kp_Nm_per_rad * servo_x, torque_limit_Nm=Servo().torque_limit_Nm * servo_x)
    ds = _pair(n, beta, dphi, record=("x", "y", "node_x"), heading_guide=True, servo=sv)
    late = ds["time"].values >= 15.0
    nx = ds["node_x"].values[late]
    return args, _steady_dx(ds) + (float(np.abs(nx[..., -1] - nx[..., 0]).mean()),)


def recoil_free():
    """The cause of the link-number failure, measured: the free body's lab-frame envelope with and without
    the heading guide; equal-A pairs with the recoil removed against the line with lambda = L and with the
    measured lambda_x; the same with 4x servo stiffness and torque (the N = 7, 9 floor)."""
    for n in (3, 9):
        for guide in (False, True):
            env, swing = _free_envelope(n, _beta("equal-A", n), guide)
            print(f"free N={n} (equal-A beta){' guided' if guide else ''}: chord swing +-{swing:.3f} rad; lateral "
                  f"excursion along the body " + " ".join(f"{e * 1e3:.0f}" for e in env) + " mm", flush=True)
    betas = {n: _guided_beta(n) for n in N_LINKS}
    for n, (b, a) in betas.items():
        print(f"recoil removed, N={n}: beta {math.degrees(b):.2f} deg gives A = {a * 1e3:.1f} mm", flush=True)
    jobs = [(n, betas[n][0], float(d), sx) for sx in (1.0, 4.0) for n in N_LINKS for d in C.paper_phases()]
    with ProcessPoolExecutor(2) as ex:
        res = list(ex.map(_recoil_free_run, jobs))
    for sx in (1.0, 4.0):
        for n in N_LINKS:
            rows = [v for a, v in res if a[0] == n and a[3] == sx]
            dx, dph, lx = (np.array([q[k] for q in rows]) for k in range(3))
            lam = lx.mean() / L_M
            r_x = C.rms(theory.compatibility_residual(dx, dph, lam) / lam)
            print(f"recoil removed, servo x{sx:g}, N={n}: lambda_x/L {lam:.3f}; "
                  + _rms_line([(a, b) for a, b, _ in rows]).replace("RMS", "RMS (lambda = L)", 1)
                  + f"; RMS (lambda = lambda_x) {r_x.value:.4f} [{r_x.low:.4f}, {r_x.high:.4f}]", flush=True)


if __name__ == "__main__":
    cmds = {"wavelength": wavelength, "attractor": attractor, "recoil": recoil, "yaw-guided": yaw_guided,
            "smooth-limit": smooth_limit, "quasi-static": quasi_static, "waves": waves, "inertia": inertia,
            "held-force": held_force, "recoil-free": recoil_free}
    if len(sys.argv) != 2 or sys.argv[1] not in cmds:
        sys.exit("usage: python explorations/links_mechanisms.py {" + ",".join(cmds) + "}")
    cmds[sys.argv[1]]()
