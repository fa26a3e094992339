"""Gait controllers: the open-loop travelling wave and two closed-loop families.

A controller turns what a swimmer's servos can sense -- joint angle (rad),
joint angular velocity (rad/s) and servo load (the servo's output torque,
N m: what a Dynamixel reports as "present load") -- into servo set-points,
at a control rate (default 100 Hz, a realistic servo-bus rate).  The
simulator steps MuJoCo in C between control updates (one ``mujoco.rollout``
chunk per control period) and calls the controller in between; a robot
driver calls the very same object with readings from its servo bus.  A
controller therefore holds nothing a robot could not hold: its own internal
state (a phase, a direction), never the simulation's.

Everything is vectorised: sensed arrays have shape ``(..., n_swimmers,
n_joints)`` with any leading batch shape, and so do the set-points.

Conventions
-----------
Every controller has a **gait phase** ``psi_j`` per swimmer (rad,
unwrapped, growing by ``2 pi`` per undulation): its joint set-points are
``alpha_i = beta sin(2 pi xi i / N - psi_j)``.  The open-loop gait of the
paper, ``alpha_i = beta sin(2 pi xi i / N - 2 pi f t + phi_j)``, is
``psi_j = 2 pi f t - phi_j``; the initial phases ``phi_j`` (``Scene.phases_rad``)
set ``psi_j(0) = -phi_j`` for every controller.  The paper's phase offset at
time ``t`` is ``phi_j(t) = 2 pi f t - psi_j(t)``
(:func:`undulate.observables.phase_offsets`).

Families (equations, units, references)
---------------------------------------
``open-loop``
    ``psi = 2 pi f t - phi``: the paper's gait.  Its set-points are the
    gait's closed form at every integrator step (bit-identical to the
    open-loop path).

``self-oscillating``
    A time-independent oscillator whose rhythm emerges from sensing the
    joints' bending angles -- the idea of the robots in Zhou, Hao & Gravish,
    "Collective synchronization of undulatory movement through contact",
    Phys. Rev. X 11, 031051 (2021), whose joints "sense and respond to
    undulatory bending angle and speed".  We could not find that paper's
    controller equations in the material available here, so this is the
    simplest model with its properties, designed here:

    * the phase advances at ``2 pi f`` and the joints follow the travelling
      wave above (body wave from a fixed lag ``2 pi xi / N`` per joint);
    * each joint's **turning points** (``alpha_i = +-beta``) are gates: the
      phase may pass joint ``i``'s turning point only once that joint's
      *measured* angle has reached ``a beta`` on that side (``a =
      arrival_fraction``, default 0.9).  An unobstructed servo tracks within
      about a milliradian, so a free swimmer never waits and keeps exactly
      ``f`` and ``beta``; a joint held back by contact holds its whole body
      at the turning point -- the swimmer falls behind in phase;
    * a joint that has stalled (measured speed below ``stall_speed_rad_s``)
      for ``max_hold_s`` (default a quarter period) releases its gate, as a
      servo's firmware gives up a blocked move: two swimmers holding each
      other at their turning points would otherwise wait forever.

``phase-oscillator``
    A phase oscillator with load feedback, the "Tegotae" rule of Owaki &
    Ishiguro (Sci. Rep. 7, 277, 2017; Owaki et al., J. R. Soc. Interface
    10, 20120669, 2013) written for joint torques::

        d psi / dt = 2 pi f - sigma sum_i tau_i (d alpha_i / d psi) / beta
                   = 2 pi f + sigma sum_i tau_i cos(2 pi xi i / N - psi)

    with ``tau_i`` the sensed servo torque (N m) and ``sigma`` the coupling
    (``coupling``, rad s^-1 per N m).  A servo pushing along its commanded
    motion (the load resists it) slows the phase; a load that helps the
    motion speeds it up.  ``sigma = 0`` is the open-loop gait.  Integrated
    by explicit Euler at the control rate.

``relay``
    The closest model we could build to the oscillator of Zhou, Hao &
    Gravish (PRX 2021) from every sentence they published (their equations
    were not found: see ``docs/controllers.md`` for what was searched).  A
    switching (relay) oscillator: each joint is driven towards its turning
    point ``+-beta`` along the travelling wave at the gait's speed, and its
    drive **reverses at the sensed angle where contact obstructs it**: when
    any joint's measured angle lags its command, against the commanded
    motion, by more than ``reverse_error_rad`` (the joint is blocked), the
    swimmer's phase runs ahead at ``reverse_rate_factor * 2 pi f`` to that
    joint's next turning point -- the blocked half-stroke ends where the
    obstacle stopped it, and the drive turns.  Nothing waits and nothing
    is timed: the command depends only on the sensed angles and the
    internal phase (the drive's position along its stroke).  An
    unobstructed servo tracks within about a milliradian, so a free
    swimmer never reverses early and keeps ``f`` and ``beta`` exactly.
    A reversal that reaches its turning point within a control period
    dwells there until the next update (at most one period, 10 ms at
    100 Hz), as a servo that reached its goal waits for the next command.

Set-points within a control period: closed-loop controllers give the target
angle and velocity at the update; the servo's position set-point then moves
on at that velocity until the next update (a goal position with a moving
speed, as a Dynamixel is commanded), so set-points are continuous in time.
"""

from __future__ import annotations

import numpy as np

from .errors import ParameterError
from .params import ControllerParams, Gait, Scene

__all__ = ["Controller", "OpenLoop", "SelfOscillating", "PhaseOscillator", "RelayOscillator", "SensingOpenLoop", "make_controller"]


class Controller:
    """Base class: a gait controller for ``n_swimmers`` swimmers of ``n_links`` links.

    ``gait`` gives ``beta``, ``xi`` and ``f``; ``rate_hz`` the control rate.
    :meth:`reset` starts the swimmers at phases ``phi`` (any leading batch
    shape); :meth:`commands` returns the set-points for the integrator steps
    of one control period, given what was sensed at its start.
    """

    kind = "base"
    feed_forward = False
    """True for a controller whose commands never depend on what it senses (it only records it):
    the simulator then steps whole chunks and calls :meth:`sense` for each control update after."""

    def __init__(self, gait: Gait, n_links: int, rate_hz: float = 100.0):
        self.gait = gait
        self.n_links = int(n_links)
        self.rate_hz = float(rate_hz)
        self.offsets_rad = 2 * np.pi * gait.waves_per_body * np.arange(self.n_links - 1) / self.n_links
        self._omega = 2 * np.pi * gait.frequency_hz
        self.psi = np.zeros(0)
        self.psi_rate = np.zeros(0)
        self.t_s = 0.0

    @property
    def omega_rad_s(self) -> float:
        """Nominal gait angular frequency 2 pi f, rad/s."""
        return self._omega

    def reset(self, phases_rad, t_s: float = 0.0) -> None:
        """Start at the paper's phase offsets ``phi`` (shape ``(..., n)``), time ``t_s``."""
        phi = np.asarray(phases_rad, dtype=float)
        self.t_s = float(t_s)
        self.psi = self._omega * self.t_s - phi
        self.psi_rate = np.full_like(self.psi, self._omega)

    def gait_phase(self, t_s) -> np.ndarray:
        """Gait phase ``psi`` (rad, unwrapped) at times ``t_s`` (shape ``T``) within the
        current control period -> ``T + (..., n)``."""
        dt = np.asarray(t_s, dtype=float) - self.t_s
        return self.psi[None] + self.psi_rate[None] * dt.reshape(-1, *([1] * self.psi.ndim))

    def _wave(self, psi: np.ndarray, psi_rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        arg = self.offsets_rad - psi[..., None]
        b = self.gait.amplitude_rad
        return b * np.sin(arg), -b * np.cos(arg) * psi_rate[..., None]

    def update(self, t_s: float, angle_rad, velocity_rad_s, load_Nm) -> None:
        """Advance the internal state to ``t_s`` from the sensed joints (shape ``(..., n, n_joints)``)."""
        raise NotImplementedError

    def commands(self, t_steps_s: np.ndarray, angle_rad=None, velocity_rad_s=None, load_Nm=None
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Set-points for the steps at times ``t_steps_s`` (shape ``T``, the first at the update).

        Senses at ``t_steps_s[0]`` (``None`` for a feed-forward controller);
        returns ``(angle_rad, velocity_rad_s)``, each ``T + (..., n, n_joints)``.
        """
        t = np.asarray(t_steps_s, dtype=float)
        if angle_rad is not None:
            self.update(float(t[0]), np.asarray(angle_rad), np.asarray(velocity_rad_s), np.asarray(load_Nm))
        psi = self.gait_phase(t)
        return self._wave(psi, self.psi_rate)


class OpenLoop(Controller):
    """The paper's open-loop travelling wave: ``psi = 2 pi f t - phi`` exactly."""

    kind = "open-loop"

    def reset(self, phases_rad, t_s: float = 0.0) -> None:
        super().reset(phases_rad, t_s)
        self.phi = np.asarray(phases_rad, dtype=float)

    def update(self, t_s, angle_rad=None, velocity_rad_s=None, load_Nm=None) -> None:
        self.t_s = float(t_s)
        self.psi = self._omega * self.t_s - self.phi

    def gait_phase(self, t_s) -> np.ndarray:
        t = np.asarray(t_s, dtype=float).reshape(-1, *([1] * self.phi.ndim))
        return self._omega * t - self.phi[None]

    def commands(self, t_steps_s, angle_rad=None, velocity_rad_s=None, load_Nm=None):
        t = np.asarray(t_steps_s, dtype=float)
        self.update(float(t[0]))
        # the gait's own closed form, term for term as Gait.joint_angles / joint_velocities
        # (bit-identical set-points), for phases of any batch shape
        g, n = self.gait, self.n_links
        tt = t.reshape(-1, *([1] * (self.phi.ndim + 1)))
        phi = self.phi[..., None]
        i = np.arange(n - 1)
        w = 2 * np.pi * g.frequency_hz
        angle = g.amplitude_rad * np.sin(2 * np.pi * g.waves_per_body * i / n - 2 * np.pi * g.frequency_hz * tt + phi)
        velocity = -w * g.amplitude_rad * np.cos(2 * np.pi * g.waves_per_body * i / n - w * tt + phi)
        return angle, velocity


class SensingOpenLoop(OpenLoop):
    """The open-loop gait (phases held) that also keeps what the servos sensed at every control
    update: ``sensed`` is a list of ``(t_s, psi, angle_rad, velocity_rad_s, load_Nm)``.

    Its commands do not depend on what it senses (``feed_forward``): the simulator rolls a whole
    chunk out in one call into C and hands it what was sensed at each control update afterwards
    (:meth:`sense`), bitwise what it would have sensed stepping one control period at a time."""

    feed_forward = True

    def reset(self, phases_rad, t_s: float = 0.0) -> None:
        super().reset(phases_rad, t_s)
        self.sensed: list = []

    def sense(self, t_s: float, angle_rad, velocity_rad_s, load_Nm) -> None:
        """Keep what the servos sensed at the control update at ``t_s`` (s)."""
        self.update(float(t_s))
        self.sensed.append((self.t_s, self.psi.copy(), np.array(angle_rad), np.array(velocity_rad_s),
                            np.array(load_Nm)))

    def commands(self, t_steps_s, angle_rad=None, velocity_rad_s=None, load_Nm=None):
        out = super().commands(t_steps_s)
        if angle_rad is not None:
            self.sense(self.t_s, angle_rad, velocity_rad_s, load_Nm)
        return out


class PhaseOscillator(Controller):
    """Phase oscillator with load feedback (Tegotae): see the module docstring.

    ``coupling``: ``sigma``, rad/s per N m.
    """

    kind = "phase-oscillator"

    def __init__(self, gait: Gait, n_links: int, rate_hz: float = 100.0, coupling: float = 0.0):
        super().__init__(gait, n_links, rate_hz)
        self.coupling = float(coupling)

    def update(self, t_s, angle_rad, velocity_rad_s, load_Nm) -> None:
        dt = float(t_s) - self.t_s
        self.psi = self.psi + self.psi_rate * dt  # to the update time at the last rate (explicit Euler)
        self.t_s = float(t_s)
        cos = np.cos(self.offsets_rad - self.psi[..., None])
        self.psi_rate = self._omega + self.coupling * (np.asarray(load_Nm) * cos).sum(axis=-1)

    def phase_velocity(self, psi, angle_rad, velocity_rad_s, load_Nm) -> np.ndarray:
        """The law above at phase ``psi`` (no state change), rad/s."""
        cos = np.cos(self.offsets_rad - np.asarray(psi)[..., None])
        return self._omega + self.coupling * (np.asarray(load_Nm) * cos).sum(axis=-1)


def _phase_velocity_doc():  # pragma: no cover - documentation anchor
    """``phase_velocity(psi, angle, velocity, load)``: the phase velocity (rad/s) the controller's law
    would command at phase ``psi`` (shape ``(..., n)``) given the sensed joints (``(..., n, n_joints)``),
    without changing its state: the phase-reduction probe of :mod:`undulate.studies.phase_interaction`."""


class SelfOscillating(Controller):
    """Self-oscillating joints gated by their sensed turning points: see the module docstring."""

    kind = "self-oscillating"

    def __init__(self, gait: Gait, n_links: int, rate_hz: float = 100.0, arrival_fraction: float = 0.9,
                 max_hold_s: float | None = None, stall_speed_rad_s: float = 0.2):
        super().__init__(gait, n_links, rate_hz)
        self.arrival_fraction = float(arrival_fraction)
        self.max_hold_s = gait.period_s / 4 if max_hold_s is None else float(max_hold_s)
        self.stall_speed_rad_s = float(stall_speed_rad_s)

    def reset(self, phases_rad, t_s: float = 0.0) -> None:
        super().reset(phases_rad, t_s)
        self.limit = np.full(self.psi.shape, np.inf)  # the phase may not pass this before the next update
        self.stalled_s = np.zeros(self.psi.shape + (self.n_links - 1,))

    def _next_turn(self, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each joint's next turning point at or after ``psi`` and its side (+1: alpha = +beta)."""
        # alpha_i = beta sin(offset_i - psi) turns where offset_i - psi = pi/2 + m pi
        arg = self.offsets_rad - psi[..., None]
        m = np.floor((arg - np.pi / 2) / np.pi + 1e-9)  # at a turning point, that one (not the next)
        turn = self.offsets_rad - np.pi / 2 - m * np.pi
        side = np.where(np.mod(m, 2) == 0, 1.0, -1.0)
        return turn, side

    def gait_phase(self, t_s) -> np.ndarray:
        free = super().gait_phase(t_s)
        return np.minimum(free, self.limit[None])

    def update(self, t_s, angle_rad, velocity_rad_s, load_Nm=None) -> None:
        dt = float(t_s) - self.t_s
        psi = np.minimum(self.psi + self._omega * dt, self.limit)  # where the set-points went
        turn, side = self._next_turn(psi)
        arrived = side * np.asarray(angle_rad) >= self.arrival_fraction * self.gait.amplitude_rad
        at_gate = turn <= psi[..., None] + 1e-9
        stalled = np.abs(np.asarray(velocity_rad_s)) < self.stall_speed_rad_s
        self.stalled_s = np.where(at_gate & ~arrived & stalled, self.stalled_s + dt, 0.0)
        released = arrived | (self.stalled_s >= self.max_hold_s)
        self.limit = np.where(released, np.inf, turn).min(axis=-1)
        self.psi, self.t_s = psi, float(t_s)
        self.psi_rate = np.where(psi >= self.limit, 0.0, self._omega)

    def phase_velocity(self, psi, angle_rad, velocity_rad_s, load_Nm) -> np.ndarray:
        """0 where a joint's gate would hold the phase (its turning point within one control period
        ahead of ``psi`` and its measured angle short of ``a beta``), else ``2 pi f``; rad/s."""
        psi = np.asarray(psi, dtype=float)
        turn, side = self._next_turn(psi)
        near = turn - psi[..., None] < self._omega / self.rate_hz
        short = side * np.asarray(angle_rad) < self.arrival_fraction * self.gait.amplitude_rad
        return np.where((near & short).any(axis=-1), 0.0, self._omega)

    def commands(self, t_steps_s, angle_rad=None, velocity_rad_s=None, load_Nm=None):
        t = np.asarray(t_steps_s, dtype=float)
        if angle_rad is not None:
            self.update(float(t[0]), angle_rad, velocity_rad_s, load_Nm)
        psi = self.gait_phase(t)
        rate = np.where(psi < self.limit[None], self._omega, 0.0)
        return self._wave(psi, rate)


class RelayOscillator(Controller):
    """Relay oscillator whose drive reverses where contact blocks a joint: see the module docstring.

    ``reverse_error_rad``: lag (rad) of a joint behind its command, against the commanded motion,
    that counts as blocked; ``reverse_rate_factor``: how much faster than ``2 pi f`` the phase
    runs to the blocked joint's turning point (the drive's reversal, > 1).
    """

    kind = "relay"

    def __init__(self, gait: Gait, n_links: int, rate_hz: float = 100.0, reverse_error_rad: float = 0.1,
                 reverse_rate_factor: float = 4.0):
        super().__init__(gait, n_links, rate_hz)
        self.reverse_error_rad = float(reverse_error_rad)
        self.reverse_rate_factor = float(reverse_rate_factor)

    def reset(self, phases_rad, t_s: float = 0.0) -> None:
        super().reset(phases_rad, t_s)
        self.target = np.full(self.psi.shape, -np.inf)  # reversing: running to this phase
        self.reversals = np.zeros(self.psi.shape, dtype=int)

    def _next_turn(self, psi: np.ndarray) -> np.ndarray:
        """Each joint's next turning point strictly after ``psi`` (rad)."""
        arg = self.offsets_rad - psi[..., None]
        m = np.ceil((arg - np.pi / 2) / np.pi - 1e-9) - 1  # offset - psi_turn = pi/2 + m pi, psi_turn > psi
        return self.offsets_rad - np.pi / 2 - m * np.pi

    def gait_phase(self, t_s) -> np.ndarray:
        free = super().gait_phase(t_s)
        fast = self.target > self.psi
        return np.where(fast[None], np.minimum(free, self.target[None]), free)

    def _blocked(self, psi: np.ndarray, angle_rad) -> np.ndarray:
        """Joints lagging their command against the commanded motion by more than the threshold."""
        arg = self.offsets_rad - psi[..., None]
        command, direction = self.gait.amplitude_rad * np.sin(arg), -np.cos(arg)  # d alpha / d psi sign
        lag = np.sign(direction) * (command - np.asarray(angle_rad))
        return (lag > self.reverse_error_rad) & (np.abs(direction) > 0.05)

    def phase_velocity(self, psi, angle_rad, velocity_rad_s, load_Nm) -> np.ndarray:
        """``reverse_rate_factor * 2 pi f`` where a joint is blocked (the drive reverses), else ``2 pi f``."""
        blocked = self._blocked(np.asarray(psi, dtype=float), angle_rad).any(axis=-1)
        return np.where(blocked, self.reverse_rate_factor * self._omega, self._omega)

    def update(self, t_s, angle_rad, velocity_rad_s=None, load_Nm=None) -> None:
        psi = self.gait_phase(np.array([float(t_s)]))[0]
        blocked = self._blocked(psi, angle_rad)
        turn = np.where(blocked, self._next_turn(psi), np.inf).min(axis=-1)
        start = np.isfinite(turn) & ~(self.target > psi)
        self.target = np.where(start, turn, self.target)
        self.reversals = self.reversals + start
        self.psi, self.t_s = psi, float(t_s)
        self.psi_rate = np.where(self.target > psi, self.reverse_rate_factor * self._omega, self._omega)

    def commands(self, t_steps_s, angle_rad=None, velocity_rad_s=None, load_Nm=None):
        t = np.asarray(t_steps_s, dtype=float)
        if angle_rad is not None:
            self.update(float(t[0]), angle_rad, velocity_rad_s, load_Nm)
        psi = self.gait_phase(t)
        fast = (self.target[None] > psi)
        rate = np.where(fast, self.reverse_rate_factor * self._omega, self._omega)
        return self._wave(psi, rate)


def make_controller(scene: Scene, params: ControllerParams | None = None) -> Controller:
    """The runtime controller for ``scene`` (its ``controller`` parameters by default), reset to
    the scene's initial phases at t = 0."""
    if not isinstance(scene, Scene):
        raise ParameterError("scene", "a Scene", type(scene).__name__)
    if params is not None and not isinstance(params, ControllerParams):
        raise ParameterError("params", "a ControllerParams or None", type(params).__name__)
    p = scene.controller if params is None else params
    g, n = scene.gait, scene.geometry.n_links
    if p.kind == "open-loop":
        c: Controller = OpenLoop(g, n, p.control_rate_hz)
    elif p.kind == "phase-oscillator":
        c = PhaseOscillator(g, n, p.control_rate_hz, coupling=p.coupling)
    elif p.kind == "self-oscillating":
        c = SelfOscillating(g, n, p.control_rate_hz, arrival_fraction=p.arrival_fraction,
                            max_hold_s=p.max_hold_s, stall_speed_rad_s=p.stall_speed_rad_s)
    elif p.kind == "relay":
        c = RelayOscillator(g, n, p.control_rate_hz, reverse_error_rad=p.reverse_error_rad,
                            reverse_rate_factor=p.reverse_rate_factor)
    else:  # pragma: no cover - ControllerParams validates the kind
        raise ValueError(p.kind)
    c.reset(np.asarray(scene.phases_rad))
    return c

