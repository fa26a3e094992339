"""The pair scene rebuilt in a second, independent 2-D engine: pymunk (Chipmunk2D).

    python tests/pymunk_pair.py            # comparison table of docs/cross_engine.md (~2 min)
    python tests/pymunk_pair.py --quick    # the same at one pymunk step only

A test-only model (``pymunk`` is in the ``test`` extra) that mirrors
:mod:`undulate.scene` physically.  It is written from the model's equations,
not from MuJoCo's code; only parameter *values* are read from the
:class:`undulate.Scene` (and :func:`undulate.scene.drag_viscosity` for the
rotational drag).  SI units throughout: m, s, kg, rad, N, N m.

Bodies (maximal coordinates: one rigid body per link)
    ``N`` links per swimmer, length ``l = L/N``, mass ``m = M/N``, moment of
    inertia of a solid ``l x w`` box about its centre (planar):
    ``I = m (l^2 + w^2) / 12`` (kg m^2).  Adjacent links are joined by
    ``PivotJoint`` constraints at their common end.  Heads point to -x: link
    ``k``'s centre starts at ``x_c - L/2 + (k + 1/2) l`` (``x_c`` the
    swimmer's centre, :meth:`undulate.Scene.initial_x_m`), all links along
    +x (body angle 0), the swimmers at :meth:`undulate.Scene.initial_y_m`.

Joint angles (the convention of :mod:`undulate.params`)
    ``alpha_i = theta_{i+1} - theta_i`` (rad), the child link's angle
    relative to its parent, counter-clockwise about +z positive, with
    ``theta_k`` the pymunk body angle of link ``k``.  Gait:
    ``alpha_i^cmd(t) = beta sin(2 pi xi i / N - 2 pi f t + phi)``
    (:meth:`undulate.params.Gait.joint_angles`).

Collision
    Each link is a ``Segment`` of radius ``r = w/2`` from ``-l/2 + r`` to
    ``l/2 - r`` along its axis: the same rounded outline as MuJoCo's
    capsules (``fromto [r, 0, 0, l - r, 0, 0]``; MuJoCo splits it into
    ``collision_segments`` capsules whose union is this one).  Friction 0,
    elasticity 0.  Adjacent links of one swimmer do not collide
    (``collide_bodies = False`` on their pivot, the exact analogue of
    MuJoCo's parent-child filter); non-adjacent links of one swimmer and
    links of different swimmers do.  The walls are static segments of
    radius ``R = 5 cm`` whose surfaces lie at ``y = -d/2`` and ``y = +d/2``
    (``x`` from -5 m to 5 m): half-spaces for all practical purposes, like
    MuJoCo's planes.
    Chipmunk contacts are *hard*: a velocity-level non-penetration
    constraint solved by sequential impulses (``iterations`` per step), plus
    a positional bias removing overlap beyond ``collision_slop`` (set to
    1 um here; pymunk's default, 0.1, is meant for pixels and would allow
    10 cm of overlap) with a time constant ``contact_timeconst_s``
    (``collision_bias = exp(-1 s / tau)``).  MuJoCo's are soft (time
    constant 2 dt).

Servo (per joint ``i`` of each swimmer; :class:`undulate.params.Servo`)
    Set-point ``s`` (the MuJoCo ``pid`` actuator's slew state, starting at
    0): each step, before the torque is computed,
    ``s <- s + clip(alpha_cmd + (b/kp) alpha_dot_cmd - s, -omega_top dt, +omega_top dt)``
    (slew limit ``omega_top = 6 rad/s``; ``(b/kp) alpha_dot_cmd`` is the
    back-EMF feed-forward the MuJoCo model adds to its position set-point).
    Torque (N m):
    ``tau = clip(kp (s - alpha) + kd (alpha_dot_cmd - alpha_dot), -tau_s, +tau_s) - b alpha_dot``
    with ``kp = 10 N m/rad``, ``kd = 0.1 N m s/rad``, ``tau_s = 1.5 N m`` and
    the DC motor's back-EMF damping ``b = tau_s / omega_top = 0.25 N m s/rad``
    (outside the saturation, as MuJoCo's joint damping is).  ``+tau`` acts
    on the child link, ``-tau`` on the parent.

Ground (:class:`undulate.params.Ground`, MuJoCo's inertia-box model at zero density)
    Each link: force ``-c v`` at its centre of mass (``c = 2 N s/m``) and
    torque ``-c_rot omega`` with ``c_rot = pi mu D^3``, ``mu = c / (3 pi D)``,
    ``D = (l + w + h) / 3`` (N m s).  A constant longitudinal force ``F``
    (``Scene.forces_N``) is spread as ``F/N`` along +x on each link's centre.

Integration
    Forces and torques (drag, servo, perturbation) are evaluated from the
    state at the start of each step and held for the step; Chipmunk then
    moves positions with the old velocities, updates velocities with the
    forces (semi-implicit Euler) and applies the constraint impulses.  The
    default step, 0.25 ms, is converged (docs/cross_engine.md).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass

import numpy as np
import pymunk

from undulate import Scene
from undulate.scene import drag_viscosity

DPHIS = (0.0, math.pi / 2, -math.pi / 2, math.pi)
"""The phase differences compared with MuJoCo, rad."""
DEFAULT_TIMESTEP_S = 0.00025
"""pymunk's step for the comparison, s (converged: 0.125 ms gives the same offsets)."""
DEFAULT_ITERATIONS = 30
"""Chipmunk solver iterations per step."""
WALL_RADIUS_M = 0.05
"""Radius of the wall segments, m (their surfaces sit at y = +-d/2)."""


def _clip(v: float, lim: float) -> float:
    return lim if v > lim else -lim if v < -lim else v


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    u = float(np.clip(np.dot(p - a, ab) / np.dot(ab, ab), 0.0, 1.0))
    return float(np.hypot(*(p - a - u * ab)))


def _segment_distance(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> float:
    """Distance between two segments in the plane, m (0 if they cross)."""
    def cross(o, p, q):
        return (p[0] - o[0]) * (q[1] - o[1]) - (p[1] - o[1]) * (q[0] - o[0])
    if cross(a0, a1, b0) * cross(a0, a1, b1) < 0 and cross(b0, b1, a0) * cross(b0, b1, a1) < 0:
        return 0.0
    return min(_point_segment_distance(a0, b0, b1), _point_segment_distance(a1, b0, b1),
               _point_segment_distance(b0, a0, a1), _point_segment_distance(b1, a0, a1))


@dataclass(frozen=True)
class Coefficients:
    """Every physical constant of the pymunk model, SI units, derived from a :class:`~undulate.Scene`."""

    n_links: int
    link_length_m: float
    width_m: float
    link_mass_kg: float
    link_inertia_kg_m2: float  # m (l^2 + w^2) / 12
    drag_N_s_per_m: float  # c
    rot_drag_N_m_s: float  # pi mu D^3
    kp: float  # N m / rad
    kd: float  # N m s / rad
    torque_limit_Nm: float
    max_speed_rad_s: float  # set-point slew limit (0: none)
    back_emf_Nms_per_rad: float  # b

    @classmethod
    def from_scene(cls, scene: Scene) -> "Coefficients":
        g, sv = scene.geometry, scene.servo
        m, l, w = g.link_mass_kg, g.link_length_m, g.width_m
        D = (l + w + g.height_m) / 3.0
        return cls(
            n_links=g.n_links, link_length_m=l, width_m=w, link_mass_kg=m,
            link_inertia_kg_m2=m * (l * l + w * w) / 12.0,
            drag_N_s_per_m=scene.ground.drag_N_s_per_m,
            rot_drag_N_m_s=math.pi * drag_viscosity(scene) * D**3,
            kp=sv.kp_Nm_per_rad, kd=sv.kd_Nms_per_rad, torque_limit_Nm=sv.torque_limit_Nm,
            max_speed_rad_s=sv.max_speed_rad_s, back_emf_Nms_per_rad=sv.back_emf_Nms_per_rad,
        )


class PymunkPair:
    """The swimmers of ``scene`` (any number; side by side, straight, as in MuJoCo) in a pymunk space.

    ``timestep_s``: integrator step, s.  ``iterations``: Chipmunk solver
    iterations.  ``contact_timeconst_s``: time constant of the positional
    overlap correction, s.  ``self_collision``: non-adjacent links of one
    swimmer collide (as in MuJoCo).
    """

    def __init__(self, scene: Scene, timestep_s: float = DEFAULT_TIMESTEP_S, iterations: int = DEFAULT_ITERATIONS,
                 contact_timeconst_s: float = 0.002, self_collision: bool = True):
        if scene.ground.mode != "viscous" or scene.channel.end_walls_m is not None or scene.servo.ki_Nm_per_rad_s:
            raise ValueError("the pymunk model covers viscous ground, side walls only and PD servos")
        self.scene, self.dt = scene, float(timestep_s)
        self.k = k = Coefficients.from_scene(scene)
        self.n = n = k.n_links
        l, r = k.link_length_m, k.width_m / 2
        self.space = space = pymunk.Space()
        space.iterations = int(iterations)
        space.gravity = (0.0, 0.0)
        space.damping = 1.0  # no global damping: the drag is applied explicitly
        space.collision_slop = 1e-6  # m of overlap tolerated before position correction
        space.collision_bias = math.exp(-1.0 / contact_timeconst_s)  # overlap fraction left after 1 s

        self.bodies: list[list[pymunk.Body]] = []
        self.shapes: list[list[pymunk.Segment]] = []
        xs, ys = scene.initial_x_m(), scene.initial_y_m()
        L = scene.geometry.length_m
        for j in range(scene.n_swimmers):
            links, segs = [], []
            x_head = xs[j] - L / 2
            for kk in range(n):
                b = pymunk.Body(k.link_mass_kg, k.link_inertia_kg_m2)
                b.position = (x_head + (kk + 0.5) * l, ys[j])
                b.angle = 0.0
                seg = pymunk.Segment(b, (-l / 2 + r, 0.0), (l / 2 - r, 0.0), r)
                seg.friction, seg.elasticity = 0.0, 0.0
                if not self_collision:
                    seg.filter = pymunk.ShapeFilter(group=j + 1)  # one group per swimmer: no self-contact
                space.add(b, seg)
                if kk > 0:
                    pivot = pymunk.PivotJoint(links[-1], b, (x_head + kk * l, ys[j]))
                    pivot.collide_bodies = False  # adjacent links never collide (MuJoCo's parent-child filter)
                    space.add(pivot)
                links.append(b)
                segs.append(seg)
            self.bodies.append(links)
            self.shapes.append(segs)
        half, R = scene.channel.width_m / 2, WALL_RADIUS_M
        self.walls = []
        for yc in (-half - R, half + R):
            wall = pymunk.Segment(space.static_body, (-5.0, yc), (5.0, yc), R)
            wall.friction, wall.elasticity = 0.0, 0.0
            space.add(wall)
            self.walls.append(wall)
        self.setpoint = np.zeros((scene.n_swimmers, n - 1))  # the servo's slewed position set-point, rad
        self.t = 0.0
        self._steps = 0

    # -- one step ---------------------------------------------------------------------------------
    def _apply_forces(self) -> None:
        """Drag, servo and perturbation from the state at the start of the step (held for the step)."""
        sc, k, dt = self.scene, self.k, self.dt
        cmd = sc.gait.joint_angles(self.t, sc.phases_rad, self.n)  # (swimmers, joints), rad
        vel = sc.gait.joint_velocities(self.t, sc.phases_rad, self.n)  # rad/s
        target = cmd + (k.back_emf_Nms_per_rad / k.kp) * vel  # back-EMF feed-forward in the set-point
        if k.max_speed_rad_s > 0:
            lim = k.max_speed_rad_s * dt
            self.setpoint += np.clip(target - self.setpoint, -lim, lim)
        else:
            self.setpoint[:] = target
        push = sc.forces_N if (sc.forces_N is not None and self.t >= sc.force_onset_s) else None
        c, c_rot = k.drag_N_s_per_m, k.rot_drag_N_m_s
        for j, links in enumerate(self.bodies):
            fx = 0.0 if push is None else push[j] / self.n
            ang, om = [], []
            for b in links:
                vx, vy = b.velocity
                w = b.angular_velocity
                b.force = (fx - c * vx, -c * vy)
                ang.append(b.angle)
                om.append(w)
                b.torque = -c_rot * w
            sp, vj = self.setpoint[j], vel[j]
            for i in range(self.n - 1):
                alpha, alpha_dot = ang[i + 1] - ang[i], om[i + 1] - om[i]
                tau = _clip(k.kp * (sp[i] - alpha) + k.kd * (vj[i] - alpha_dot), k.torque_limit_Nm)
                tau -= k.back_emf_Nms_per_rad * alpha_dot
                links[i + 1].torque += tau
                links[i].torque -= tau

    def step(self) -> None:
        self._apply_forces()
        self.space.step(self.dt)
        self._steps += 1
        self.t = self._steps * self.dt

    # -- observation -------------------------------------------------------------------------------
    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Centre of mass (x, y) of each swimmer, m (equal links: the mean of the link centres)."""
        p = np.array([[tuple(b.position) for b in links] for links in self.bodies])
        return p[..., 0].mean(axis=1), p[..., 1].mean(axis=1)

    def joint_angles(self) -> np.ndarray:
        """``alpha_i = theta_{i+1} - theta_i`` per swimmer and joint, rad."""
        th = np.array([[b.angle for b in links] for links in self.bodies])
        return np.diff(th, axis=1)

    def nodes(self) -> tuple[np.ndarray, np.ndarray]:
        """Centre-line nodes head..tail (N + 1 per swimmer), m: link ends along each link's axis."""
        h = self.k.link_length_m / 2
        nx, ny = [], []
        for links in self.bodies:
            c = np.array([tuple(b.position) for b in links])
            th = np.array([b.angle for b in links])
            d = h * np.stack([np.cos(th), np.sin(th)], axis=1)
            pts = np.concatenate([c - d, (c[-1] + d[-1])[None]], axis=0)
            nx.append(pts[:, 0])
            ny.append(pts[:, 1])
        return np.array(nx), np.array(ny)

    def _axes(self) -> list[tuple[int, int, np.ndarray, np.ndarray]]:
        """(swimmer, link, end a, end b) of every link's collision segment in world coordinates, m."""
        out = []
        for j, segs in enumerate(self.shapes):
            for kk, s in enumerate(segs):
                b = s.body
                out.append((j, kk, np.array(tuple(b.local_to_world(s.a))), np.array(tuple(b.local_to_world(s.b)))))
        return out

    def penetration(self) -> float:
        """Deepest overlap now among all pairs that can collide (links of different swimmers,
        non-adjacent links of one swimmer, links and walls), m (0 if none)."""
        r, half = self.k.width_m / 2, self.scene.channel.width_m / 2
        axes = self._axes()
        deepest = 0.0
        for ia, (ja, ka, a0, a1) in enumerate(axes):
            deepest = max(deepest, max(abs(a0[1]), abs(a1[1])) + r - half)  # walls
            for jb, kb, b0, b1 in axes[ia + 1:]:
                if ja == jb and abs(ka - kb) < 2:
                    continue
                deepest = max(deepest, 2 * r - _segment_distance(a0, a1, b0, b1))
        return max(deepest, 0.0)

    def run(self, duration_s: float, sample_rate_hz: float = 20.0) -> dict[str, np.ndarray]:
        """Step for ``duration_s`` (s) from the current state; sample at ``sample_rate_hz`` (and at the start).

        Returns ``time`` (s, T), ``x``, ``y`` (centre of mass, m, T x swimmers), ``alpha`` (joint
        angles, rad, T x swimmers x joints), ``node_x``, ``node_y`` (m, T x swimmers x (N+1)) and
        ``penetration`` (deepest overlap, m, T).
        """
        per = max(1, int(round(1.0 / (sample_rate_hz * self.dt))))
        n_steps = int(round(duration_s / self.dt))
        out: dict[str, list] = {key: [] for key in ("time", "x", "y", "alpha", "node_x", "node_y", "penetration")}

        def sample() -> None:
            x, y = self.centres()
            nx, ny = self.nodes()
            out["time"].append(self.t)
            out["x"].append(x)
            out["y"].append(y)
            out["alpha"].append(self.joint_angles())
            out["node_x"].append(nx)
            out["node_y"].append(ny)
            out["penetration"].append(self.penetration())

        if self._steps == 0:
            sample()
        for s in range(1, n_steps + 1):
            self.step()
            if s % per == 0:
                sample()
        return {key: np.asarray(v) for key, v in out.items()}


def build_pair(scene: Scene, timestep_s: float = DEFAULT_TIMESTEP_S, **kwargs) -> PymunkPair:
    """The scene's swimmers in a fresh pymunk space (see :class:`PymunkPair`)."""
    return PymunkPair(scene, timestep_s, **kwargs)


def run_pair(scene: Scene, duration_s: float = 30.0, timestep_s: float = DEFAULT_TIMESTEP_S,
             sample_rate_hz: float = 20.0, **kwargs) -> dict[str, np.ndarray]:
    """Build and run; the time series of :meth:`PymunkPair.run`."""
    return build_pair(scene, timestep_s, **kwargs).run(duration_s, sample_rate_hz)


def steady_dx_over_lambda(traj: dict, scene: Scene) -> float:
    """Mean over the last gait period, samples in ``(t_end - T, t_end]``, of
    ``(x_upper - x_lower) / lambda`` (upper: the swimmer with the larger mean y there)."""
    t = np.asarray(traj["time"])
    last = t > t[-1] - scene.gait.period_s + 1e-9
    x, y = np.asarray(traj["x"])[last], np.asarray(traj["y"])[last]
    up, lo = (1, 0) if y[:, 1].mean() > y[:, 0].mean() else (0, 1)
    return float((x[:, up] - x[:, lo]).mean() / scene.wavelength_m)


def mujoco_run(scene: Scene, duration_s: float = 30.0, timestep_s: float | None = None):
    """``undulate.simulate(scene, SimOptions(duration_s=...))``: the package's current defaults
    (its automatic time step unless ``timestep_s`` is given).  Returns the dataset."""
    from undulate import SimOptions, simulate

    return simulate(scene, SimOptions(duration_s=duration_s, timestep_s=timestep_s))


def mujoco_dx_over_lambda(ds, scene: Scene) -> float:
    """MuJoCo's steady offset: mean over the last gait period, samples in ``(t_end - T, t_end]``,
    of ``neighbour_offsets(ds)["dx"] / wavelength`` (the README's recipe)."""
    from undulate import neighbour_offsets

    dxl = neighbour_offsets(ds)["dx"].isel(pair=0) / ds.attrs["wavelength"]
    t = ds["time"].values
    last = t > t[-1] - scene.gait.period_s + 1e-9
    return float(dxl.values[last].mean())


def mujoco_steady_dx_over_lambda(scene: Scene, duration_s: float = 30.0,
                                 timestep_s: float | None = None) -> tuple[float, float]:
    """Run MuJoCo (:func:`mujoco_run`) and return ``(dx / lambda, time step used in s)``."""
    ds = mujoco_run(scene, duration_s, timestep_s)
    return mujoco_dx_over_lambda(ds, scene), float(ds.attrs["timestep"])


def pair_scene(dphi_rad: float) -> Scene:
    """The compared scene: package defaults, phases (0, dphi)."""
    return Scene(phases_rad=(0.0, float(dphi_rad)))


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="pymunk at its default step only; no MuJoCo dt/2 run")
    ap.add_argument("--duration", type=float, default=30.0, help="simulated time, s (default 30)")
    args = ap.parse_args(argv)
    dt1, dt2 = DEFAULT_TIMESTEP_S, DEFAULT_TIMESTEP_S / 2
    print(f"pymunk {pymunk.version} (Chipmunk {pymunk.chipmunk_version.split('-')[0]}), "
          f"{args.duration:g} s runs, steady = mean over the last gait period")
    print("| Δφ | MuJoCo Δx/λ (dt) | MuJoCo at dt/2 | pymunk Δx/λ (0.25 ms) | pymunk (0.125 ms) "
          "| MuJoCo − pymunk | max overlap after 2 s, mm: MuJoCo / pymunk | wall s: MuJoCo / pymunk |")
    print("|---|---|---|---|---|---|---|---|")
    for dphi in DPHIS:
        sc = pair_scene(dphi)
        t0 = time.perf_counter()
        ds = mujoco_run(sc, args.duration)
        wall_mj = time.perf_counter() - t0
        mj, dt_mj = mujoco_dx_over_lambda(ds, sc), float(ds.attrs["timestep"])
        pen_mj = float(ds["penetration"].values[ds["time"].values >= 2.0].max()) * 1e3
        mj2 = float("nan") if args.quick else mujoco_steady_dx_over_lambda(sc, args.duration, dt_mj / 2)[0]
        t0 = time.perf_counter()
        tr = run_pair(sc, args.duration, dt1)
        wall_pm = time.perf_counter() - t0
        pm = steady_dx_over_lambda(tr, sc)
        pm2 = float("nan") if args.quick else steady_dx_over_lambda(run_pair(sc, args.duration, dt2), sc)
        pen_pm = float(tr["penetration"][tr["time"] >= 2.0].max()) * 1e3
        diff = f"{mj - pm:+.5f}"
        if abs(abs(dphi) - math.pi) < 1e-9 and np.sign(mj) != np.sign(pm):
            diff += f" (other branch; \\|Δx\\|: {abs(mj) - abs(pm):+.5f})"
        print(f"| {dphi / math.pi:+.2f} π | {mj:+.4f} ({dt_mj * 1e3:.3g} ms) | {mj2:+.4f} | {pm:+.4f} | {pm2:+.4f} "
              f"| {diff} | {pen_mj:.3f} / {pen_pm:.3f} | {wall_mj:.1f} / {wall_pm:.1f} |", flush=True)


if __name__ == "__main__":
    sys.exit(main())
