"""The pair scene rebuilt in a second, independent 2-D engine: pymunk (Chipmunk2D).

    python tests/pymunk_pair.py          # the comparison table of docs/cross_engine.md

A test-only model (``pymunk`` is in the ``test`` extra) that mirrors
:mod:`undulate.scene` physically, written from the equations, not from
MuJoCo's code:

* **Bodies.**  N rigid links per swimmer, mass ``M/N``, moment of inertia
  of a solid ``l x w`` box about its centre, ``m (l^2 + w^2) / 12`` (kg m^2),
  joined by pivot joints at the link ends.  Heads toward -x; link ``k``'s
  centre starts at ``x_head + (k + 1/2) l``.
* **Collision.**  Each link is a pymunk ``Segment`` of radius ``w/2`` whose
  axis is inset by ``w/2`` from the link's ends (the same rounded body as
  MuJoCo's capsule union); frictionless, inelastic.  Links of one swimmer
  never collide with each other (one collision group per swimmer: for 3
  links at 45 degrees the non-adjacent head and tail cannot meet).  Two
  static walls at ``y = +-d/2``.  Chipmunk's contacts are hard
  (iterative impulses with a small slop), MuJoCo's are soft.
* **Servos** (per joint, torque on the child link and the opposite torque
  on the parent): the set-point ``s`` moves toward the command
  ``alpha_cmd + (b / kp) omega_cmd`` by at most ``omega_top dt`` per step
  (slew limit), then
  ``tau = clip(kp (s - alpha) + kd (omega_cmd - alpha_dot), +-tau_s) - b alpha_dot``
  with ``b = tau_s / omega_top`` the DC motor's back-EMF
  (:class:`undulate.params.Servo`).  ``alpha`` is the child's angle relative
  to the parent, counter-clockwise.
* **Ground.**  Each link feels ``F = -c v`` at its centre of mass and the
  torque ``-pi mu D^3 omega`` of MuJoCo's inertia-box model with
  ``mu = c / (3 pi D)``, ``D = (l + w + h) / 3`` (:func:`undulate.scene.drag_viscosity`).
* **Integration.**  Chipmunk's semi-implicit Euler at ``dt`` with forces
  (drag, servo) evaluated from the state at the start of each step.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pymunk

from undulate import Scene
from undulate.scene import drag_viscosity


def _clip(v: float, lim: float) -> float:
    return lim if v > lim else -lim if v < -lim else v


class PymunkPair:
    """Swimmers of ``scene`` (side by side, straight, laterally in contact) in a pymunk space."""

    def __init__(self, scene: Scene, timestep_s: float = 0.00025, iterations: int = 30):
        g, sv, gait = scene.geometry, scene.servo, scene.gait
        self.scene, self.dt = scene, float(timestep_s)
        self.n, self.l = g.n_links, g.link_length_m
        self.space = pymunk.Space()
        self.space.iterations = iterations
        self.space.gravity = (0.0, 0.0)
        m, l, w = g.link_mass_kg, g.link_length_m, g.width_m
        inertia = m * (l * l + w * w) / 12.0
        r = w / 2
        self.c = scene.ground.drag_N_s_per_m
        D = (l + w + g.height_m) / 3.0
        self.c_rot = math.pi * drag_viscosity(scene) * D**3
        self.kp, self.kd, self.tau_s = sv.kp_Nm_per_rad, sv.kd_Nms_per_rad, sv.torque_limit_Nm
        self.top, self.b = sv.max_speed_rad_s, sv.back_emf_Nms_per_rad
        self.gait = gait
        self.bodies: list[list[pymunk.Body]] = []
        xs, ys = scene.initial_x_m(), scene.initial_y_m()
        for j in range(scene.n_swimmers):
            links = []
            x_head = xs[j] - g.length_m / 2
            for k in range(self.n):
                b = pymunk.Body(m, inertia)
                b.position = (x_head + (k + 0.5) * l, ys[j])
                seg = pymunk.Segment(b, (-l / 2 + r, 0.0), (l / 2 - r, 0.0), r)
                seg.friction, seg.elasticity = 0.0, 0.0
                seg.filter = pymunk.ShapeFilter(group=j + 1)
                self.space.add(b, seg)
                if k > 0:
                    joint = pymunk.PivotJoint(links[-1], b, (x_head + k * l, ys[j]))
                    joint.collide_bodies = False
                    self.space.add(joint)
                links.append(b)
            self.bodies.append(links)
        half = scene.channel.width_m / 2
        for y in (-half, half):
            wall = pymunk.Segment(self.space.static_body, (-5.0, y), (5.0, y), 0.0)
            wall.friction, wall.elasticity = 0.0, 0.0
            self.space.add(wall)
        self.setpoint = np.zeros((scene.n_swimmers, self.n - 1))
        self.t = 0.0

    def _servo_and_drag(self) -> None:
        sc, dt = self.scene, self.dt
        cmd = self.gait.joint_angles(self.t, sc.phases_rad, self.n)  # (swimmers, joints)
        vel = self.gait.joint_velocities(self.t, sc.phases_rad, self.n)
        target = cmd + (self.b / self.kp) * vel
        step = self.top * dt if self.top > 0 else np.inf
        self.setpoint += np.clip(target - self.setpoint, -step, step)
        push = sc.forces_N if sc.forces_N is not None and self.t >= sc.force_onset_s else None
        for j, links in enumerate(self.bodies):
            fx = 0.0 if push is None else push[j] / self.n  # the perturbation, spread over the links
            for b in links:
                b.force = (fx - self.c * b.velocity.x, -self.c * b.velocity.y)
                b.torque = -self.c_rot * b.angular_velocity
            for i in range(self.n - 1):
                parent, child = links[i], links[i + 1]
                alpha = child.angle - parent.angle
                alpha_dot = child.angular_velocity - parent.angular_velocity
                tau = _clip(self.kp * (self.setpoint[j, i] - alpha) + self.kd * (vel[j, i] - alpha_dot), self.tau_s)
                tau -= self.b * alpha_dot
                child.torque += tau
                parent.torque -= tau

    def run(self, duration_s: float, sample_interval_s: float = 0.05) -> dict:
        """Step for ``duration_s``; returns sampled ``time`` (s), centre of mass ``x``, ``y`` (m) and
        ``alpha`` (rad) per swimmer."""
        per = max(1, int(round(sample_interval_s / self.dt)))
        n_steps = int(round(duration_s / self.dt))
        out = {"time": [], "x": [], "y": [], "alpha": []}

        def sample():
            out["time"].append(self.t)
            out["x"].append([np.mean([b.position.x for b in links]) for links in self.bodies])
            out["y"].append([np.mean([b.position.y for b in links]) for links in self.bodies])
            out["alpha"].append([[links[i + 1].angle - links[i].angle for i in range(self.n - 1)]
                                 for links in self.bodies])

        sample()
        for k in range(n_steps):
            self._servo_and_drag()
            self.space.step(self.dt)
            self.t = (k + 1) * self.dt
            if (k + 1) % per == 0:
                sample()
        return {key: np.asarray(v) for key, v in out.items()}


def steady_dx_over_lambda(traj: dict, scene: Scene) -> float:
    """Mean over the last gait period of ``(x_upper - x_lower) / lambda`` (upper: larger mean y)."""
    t = traj["time"]
    last = t >= t[-1] - scene.gait.period_s + 1e-9
    x, y = traj["x"][last], traj["y"][last]
    up, lo = (1, 0) if y[:, 1].mean() > y[:, 0].mean() else (0, 1)
    return float((x[:, up] - x[:, lo]).mean() / scene.wavelength_m)


def mujoco_dx_over_lambda(scene: Scene, duration_s: float = 30.0) -> float:
    from undulate import SimOptions, neighbour_offsets, simulate

    ds = simulate(scene, SimOptions(duration_s=duration_s))
    off = neighbour_offsets(ds)
    last = ds["time"] >= ds["time"][-1] - scene.gait.period_s + 1e-9
    return float(off["dx"].where(last).mean()) / scene.wavelength_m


DPHIS = (0.0, math.pi / 2, -math.pi / 2, math.pi)


def main() -> None:
    print("| Δφ | MuJoCo Δx/λ | pymunk Δx/λ (dt 0.25 ms) | pymunk (dt 0.125 ms) | MuJoCo − pymunk | pymunk wall s |")
    print("|---|---|---|---|---|---|")
    for dphi in DPHIS:
        sc = Scene(phases_rad=(0.0, dphi))
        mj = mujoco_dx_over_lambda(sc)
        t0 = time.perf_counter()
        pm = steady_dx_over_lambda(PymunkPair(sc, 0.00025).run(30.0), sc)
        wall = time.perf_counter() - t0
        pm2 = steady_dx_over_lambda(PymunkPair(sc, 0.000125).run(30.0), sc)
        print(f"| {dphi / math.pi:+.2f} π | {mj:+.4f} | {pm:+.4f} | {pm2:+.4f} | {mj - pm:+.4f} | {wall:.1f} |")


if __name__ == "__main__":
    main()
