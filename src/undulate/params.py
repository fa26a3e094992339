"""Frozen, validated parameter types.  SI units everywhere.

Every physical field carries its unit in its name (``_m``, ``_rad``,
``_hz``, ``_kg``, ``_s``, ``_N``...) and in its docstring.  Construction
validates; an invalid value raises :class:`~undulate.errors.ParameterError`
naming the field.

Conventions (fixed here, used by the simulator, theory and plots)
-----------------------------------------------------------------
* Swimmers lie along the channel axis ``x``; lateral direction ``y``.
* Link 0 is the **head**; joint ``i`` joins link ``i`` and ``i+1``.  Heads
  point to **-x**, so the body wave (travelling head to tail, increasing
  joint index) travels toward **+x** in the world, exactly as in the theory's
  ``y = A sin(2 pi x / lambda - omega t + phi)``.
* For two lateral neighbours ``a`` (lower y) and ``b`` (upper y):
  ``dx = x_b - x_a`` and ``dphi = phi_b - phi_a``.  Compatibility is then
  ``dx = lambda dphi / (2 pi)`` (positive slope).
* Angles are radians inside; only the CLI takes degrees, and says so.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import schema as _schema
from .errors import ParameterError

MUJOCO_MINVAL = 1e-15
"""MuJoCo's ``mjMINVAL``: the least mass and moment of inertia its compiler accepts for a moving body."""
INERTIA_FIELDS = "mass_kg / length_m / width_m / height_m"
"""The name a :class:`SwimmerGeometry` refusal of its link's inertia gives (the fields that set it)."""

__all__ = [
    "Gait",
    "SwimmerGeometry",
    "Servo",
    "Ground",
    "Channel",
    "ContactModel",
    "ControllerParams",
    "Scene",
    "SimOptions",
]


def _finite(name: str, value: float) -> float:
    if isinstance(value, (str, bytes, bool, np.bool_)):  # float("1") and float(True) would pass, stored as given
        raise ParameterError(name, "a finite number", value)
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ParameterError(name, "a finite number", value) from None
    if not math.isfinite(v):
        raise ParameterError(name, "a finite number", value)
    return v


def _finite_values(name: str, value, allowed: str) -> tuple[float, ...]:
    """``value``, a scalar or a flat sequence of finite real numbers, as a tuple of floats; else a
    ParameterError naming ``name`` and ``allowed``, with the whole value."""
    try:
        items = (value,) if np.ndim(value) == 0 else value
        if isinstance(value, (str, bytes)) or np.ndim(items) != 1:
            raise TypeError
        return tuple(_finite(name, v) for v in items)
    except (TypeError, ValueError):  # a ragged sequence, a non-number (a ParameterError is a ValueError)
        raise ParameterError(name, allowed, value) from None


def _positive(name: str, value: float, unit: str = "") -> float:
    v = _finite(name, value)
    if v <= 0:
        raise ParameterError(name, f"> 0{(' ' + unit) if unit else ''}", value)
    return v


def _nonneg(name: str, value: float, unit: str = "") -> float:
    v = _finite(name, value)
    if v < 0:
        raise ParameterError(name, f">= 0{(' ' + unit) if unit else ''}", value)
    return v


def _flag(name: str, value) -> bool:
    """``value`` as a bool if it is one (Python's or NumPy's); else a ParameterError naming ``name``
    (``"no"`` or ``0.5`` would be taken as true)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ParameterError(name, "True or False", value)
    return bool(value)


def _count(name: str, value, low: int, high: int | None = None) -> int:
    """An integer in ``[low, high]`` (``high`` None: no bound); a bool or a fraction is refused."""
    allowed = f"an integer >= {low}" if high is None else f"an integer in [{low}, {high}]"
    if isinstance(value, (bool, np.bool_, str, bytes)):
        raise ParameterError(name, allowed, value)
    try:
        n = int(value)
        whole = n == value
    except (TypeError, ValueError, OverflowError):
        raise ParameterError(name, allowed, value) from None
    if not whole or n < low or (high is not None and n > high):
        raise ParameterError(name, allowed, value)
    return n


def _unit(desc: str) -> Any:
    return field(metadata={"doc": desc})


class _Params:
    """Mixin: conversion to a plain dict (for provenance) and field docs."""

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            v = getattr(self, f.name)
            if isinstance(v, _Params):
                v = v.to_dict()
            elif isinstance(v, tuple):
                v = list(v)
            out[f.name] = v
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]):
        names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
        unknown = sorted(set(d) - set(names))
        if unknown:
            raise ParameterError(f"{cls.__name__}.{unknown[0]}", "one of the fields " + ", ".join(names),
                                 d[unknown[0]])
        kwargs = {}
        for f in dataclasses.fields(cls):  # type: ignore[arg-type]
            if f.name not in d:
                continue
            v = d[f.name]
            sub = _NESTED.get((cls.__name__, f.name))
            if sub is not None and isinstance(v, dict):
                v = sub.from_dict(v)
            elif isinstance(v, list):
                v = tuple(v)
            kwargs[f.name] = v
        return cls(**kwargs)


@dataclass(frozen=True)
class Gait(_Params):
    """Travelling-wave gait, paper Eq. (1).

    Joint ``i`` (``0..N-2``, 0 nearest the head) of a swimmer with phase
    ``phi`` follows ``alpha_i(t) = beta sin(2 pi xi i / N - 2 pi f t + phi)``.
    ``xi = 0`` is the standing wave (all joints in phase; the paper's
    "lambda/L = 0" case).
    """

    amplitude_rad: float = math.radians(45.0)
    """beta: joint angle amplitude, rad.  Allowed: (0, pi/2]."""
    waves_per_body: float = 1.0
    """xi = L / lambda: number of body waves on the body, dimensionless, >= 0."""
    frequency_hz: float = 0.5
    """f: gait frequency, Hz, > 0."""

    def __post_init__(self):
        a = _positive("amplitude_rad", self.amplitude_rad, "rad")
        if a > math.pi / 2:
            raise ParameterError("amplitude_rad", "in (0, pi/2] rad (0 to 90 degrees)", self.amplitude_rad)
        xi = _nonneg("waves_per_body", self.waves_per_body)
        if xi > 10:
            raise ParameterError("waves_per_body", "in [0, 10]", self.waves_per_body)
        _positive("frequency_hz", self.frequency_hz, "Hz")
        object.__setattr__(self, "amplitude_rad", a)
        object.__setattr__(self, "waves_per_body", xi)
        object.__setattr__(self, "frequency_hz", float(self.frequency_hz))

    @property
    def period_s(self) -> float:
        """Gait period 1/f, s."""
        return 1.0 / self.frequency_hz

    @property
    def angular_frequency_rad_s(self) -> float:
        """omega = 2 pi f, rad/s."""
        return 2.0 * math.pi * self.frequency_hz

    def wavelength_m(self, body_length_m: float) -> float:
        """lambda = L / xi, m (``inf`` for the standing wave xi = 0)."""
        return math.inf if self.waves_per_body == 0 else body_length_m / self.waves_per_body

    def joint_angles(self, t_s, phase_rad, n_links: int) -> np.ndarray:
        """Commanded joint angles, rad.

        ``t_s``: times, s (any shape ``T``); ``phase_rad``: per-swimmer phases
        (shape ``S``).  Returns shape ``T + S + (n_links - 1,)``.
        """
        t = np.asarray(t_s, dtype=float)[..., None, None]
        phi = np.asarray(phase_rad, dtype=float)[..., None]
        i = np.arange(n_links - 1)
        return self.amplitude_rad * np.sin(
            2 * np.pi * self.waves_per_body * i / n_links - 2 * np.pi * self.frequency_hz * t + phi
        )

    def joint_velocities(self, t_s, phase_rad, n_links: int) -> np.ndarray:
        """Time derivative of :meth:`joint_angles`, rad/s, same shape."""
        t = np.asarray(t_s, dtype=float)[..., None, None]
        phi = np.asarray(phase_rad, dtype=float)[..., None]
        i = np.arange(n_links - 1)
        w = 2 * np.pi * self.frequency_hz
        return -w * self.amplitude_rad * np.cos(
            2 * np.pi * self.waves_per_body * i / n_links - w * t + phi
        )


@dataclass(frozen=True)
class SwimmerGeometry(_Params):
    """Body of one swimmer: ``n_links`` equal rigid boxes in a row."""

    n_links: int = 3
    """N: number of links, >= 2 (N-1 actuated joints)."""
    length_m: float = 0.54
    """L: total body length, m (each link is L/N long)."""
    width_m: float = 0.015
    """w: link width (lateral thickness), m."""
    height_m: float = 0.05
    """h: link height, m (out of plane; sets only inertia and drawing)."""
    mass_kg: float = 0.3
    """Total swimmer mass, kg (split equally over the links)."""
    collision_shape: str = "capsule"
    """``"capsule"`` (default: radius w/2 spanning the link; same flanks as the
    box, rounded ends, one analytic test per pair) or ``"box"`` (l x w x h)."""
    collision_segments: int = 2
    """Capsules per link (``collision_shape="capsule"``): the link's capsule is
    split into this many capsules whose union is the same body (their axes
    tile the link's), so two nearly parallel links touch at up to two points
    per segment pair instead of one.  MuJoCo's capsule-capsule test returns a
    single contact at the closest points (two only when exactly parallel); with
    one capsule per link that contact jumps between the ends of the overlap
    from step to step and the free end rocks inward, 1-5 mm deep in jammed
    packs (docs/contact.md).  Two segments halve that lever; 1 restores the
    single capsule."""

    def __post_init__(self):
        try:
            n = int(self.n_links)
        except (TypeError, ValueError, OverflowError):
            raise ParameterError("n_links", "an integer >= 2", self.n_links) from None
        if n != self.n_links or n < 2 or n > 64:
            raise ParameterError("n_links", "an integer in [2, 64]", self.n_links)
        object.__setattr__(self, "n_links", n)
        L = _positive("length_m", self.length_m, "m")
        w = _positive("width_m", self.width_m, "m")
        _positive("height_m", self.height_m, "m")
        _positive("mass_kg", self.mass_kg, "kg")
        if self.collision_shape not in ("capsule", "box"):
            raise ParameterError("collision_shape", "'capsule' or 'box'", self.collision_shape)
        if isinstance(self.collision_segments, bool) or self.collision_segments not in range(1, 9):
            raise ParameterError("collision_segments", "an integer in [1, 8]", self.collision_segments)
        if w >= L / n:
            raise ParameterError("width_m", f"smaller than the link length L/N = {L / n:g} m", self.width_m)
        self._check_inertia()

    def _check_inertia(self) -> None:
        """Refuse a link whose box inertia MuJoCo's compiler rejects, with the rules it applies: every
        principal moment (and the mass) of a moving body at least ``mjMINVAL`` = 1e-15, and any two
        moments at least the third, compared in floating point (a box thinner than ~1e-8 of its
        length rounds the margin ``m w^2 / 6`` away)."""
        moments = self.link_inertia_kg_m2
        if not all(math.isfinite(v) for v in moments):  # m l^2 / 12 past float64's range
            raise ParameterError(INERTIA_FIELDS, "a link whose moments of inertia are "
                                 f"finite (here {max(moments):g} kg m^2: overflowed)", None)
        if self.link_mass_kg < MUJOCO_MINVAL or min(moments) < MUJOCO_MINVAL:
            raise ParameterError(
                INERTIA_FIELDS,
                f"a link whose mass and principal moments of inertia are at least {MUJOCO_MINVAL:g} (MuJoCo's "
                f"mjMINVAL; here {self.link_mass_kg:.3g} kg and {min(moments):.3g} kg m^2)", None)
        a, b, c = moments
        if a + b < c or a + c < b or b + c < a:
            thin = "width_m" if self.width_m <= self.height_m else "height_m"
            raise ParameterError(thin, f"at least ~1e-8 of the link length ({self.link_length_m:g} m): thinner "
                                 "links' moments of inertia fail MuJoCo's A + B >= C in floating point",
                                 getattr(self, thin))

    @property
    def link_inertia_kg_m2(self) -> tuple[float, float, float]:
        """Principal moments of one link, a solid box ``l x w x h`` of mass ``M/N``, about its
        length, width and height axes, kg m^2."""
        m, a, b, c = self.link_mass_kg, self.link_length_m, self.width_m, self.height_m
        return (m * (b * b + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + b * b) / 12)

    @property
    def link_length_m(self) -> float:
        """l = L/N, m."""
        return self.length_m / self.n_links

    @property
    def link_mass_kg(self) -> float:
        """Mass of one link, kg."""
        return self.mass_kg / self.n_links


@dataclass(frozen=True)
class Servo(_Params):
    """Joint position servo: PID torque control with torque saturation.

    ``tau = clip(kp e + kd de/dt + ki int(e) dt, -torque_limit, +torque_limit)``
    with ``e = alpha_cmd - alpha``, implemented by MuJoCo's own ``pid``
    actuator with position and velocity set-points (the velocity set-point is
    the gait's ``dalpha_cmd/dt``, so the derivative acts on the tracking
    error) and ``forcerange`` for the saturation.

    The defaults model a Dynamixel AX-12A (stall torque 1.5 N m), whose
    firmware runs proportional control with no integral term (``ki = 0``);
    ``kp`` is stiff enough that an unobstructed joint tracks the gait closely
    (RMS error measured in tests/test_simulation.py).
    """

    kp_Nm_per_rad: float = 10.0
    """Proportional gain, N m / rad."""
    kd_Nms_per_rad: float = 0.1
    """Derivative gain on the tracking-error rate, N m s / rad."""
    torque_limit_Nm: float = 1.5
    """Saturation (stall) torque, N m."""
    ki_Nm_per_rad_s: float = 0.0
    """Integral gain, N m / (rad s); 0 disables the integral state."""
    integral_limit_rad_s: float = 0.0
    """Anti-windup clamp on the integrated error, rad s (0 = unclamped)."""
    max_speed_rad_s: float = 6.0
    """The servo's top (no-load) speed, rad/s (AX-12A: about 6 rad/s).  It
    slew-limits the position set-point (the start from a straight body is a
    fast ramp instead of an impulsive snap) and, with ``back_emf``, bounds
    the joint's own speed.  0 = unlimited (and no back-EMF)."""
    back_emf: bool = True
    """Model the DC motor's back-EMF: the torque the motor can deliver falls
    linearly from ``torque_limit_Nm`` at rest to zero at ``max_speed_rad_s``,
    ``tau = clip(u, -tau_s, tau_s) - b omega`` with ``b = tau_s / omega_max``
    (a joint damping, integrated implicitly), and the controller feeds
    ``b omega_cmd`` forward inside the saturation, so unobstructed tracking
    is the PID's with ``kd + b`` on the error rate.  Without it a joint held
    off its gait in a jammed pack and then released whips at up to 50 rad/s
    (measured), eight times the servo's top speed, and strikes its neighbour
    at 3 m/s or more: deep, nonphysical interpenetration (docs/contact.md)."""

    @property
    def back_emf_Nms_per_rad(self) -> float:
        """b = torque_limit / max_speed, N m s / rad (0 without back-EMF)."""
        if not self.back_emf or self.max_speed_rad_s <= 0:
            return 0.0
        return self.torque_limit_Nm / self.max_speed_rad_s

    def __post_init__(self):
        _positive("kp_Nm_per_rad", self.kp_Nm_per_rad, "N m/rad")
        _nonneg("kd_Nms_per_rad", self.kd_Nms_per_rad, "N m s/rad")
        _positive("torque_limit_Nm", self.torque_limit_Nm, "N m")
        _nonneg("ki_Nm_per_rad_s", self.ki_Nm_per_rad_s, "N m/(rad s)")
        _nonneg("integral_limit_rad_s", self.integral_limit_rad_s, "rad s")
        _nonneg("max_speed_rad_s", self.max_speed_rad_s, "rad/s")
        _flag("back_emf", self.back_emf)


@dataclass(frozen=True)
class Ground(_Params):
    """How the surroundings resist each link's motion.

    ``mode="viscous"`` (default, the paper's robots on a table): isotropic
    linear drag on each link's centre of mass, ``F = -c v`` with
    ``c = drag_N_s_per_m`` per link, plus the matching rotational drag of
    MuJoCo's Stokes model (see :mod:`undulate.scene`).  Overdamped: with the
    default mass the velocity relaxation time is ``m_link / c = 0.05 s``.
    Isotropic drag cannot propel a swimmer: a lone swimmer stays in place.

    ``mode="resistive"`` (viscous swimming, resistive-force theory): linear
    drag per link, anisotropic in the link's own frame, at the link's
    centre: ``F_par = -c_par v_par`` along the link's axis and
    ``F_perp = -c_perp v_perp`` across it, with ``c_par = drag_N_s_per_m``
    and ``c_perp = drag_anisotropy * c_par`` (both per link, N s/m; per
    unit length they are ``c / l``), plus the rotational drag of a rod of
    length ``l`` whose every element feels ``c_perp / l`` across it:
    ``tau = -(c_perp / l) l^3 / 12 omega = -c_perp l^2 / 12 omega``.  This is
    the whole medium (no isotropic part is added: the isotropic limit is
    ``drag_anisotropy = 1``).  ``c_perp > c_par`` makes a lone swimmer
    advance head first (toward -x); ``drag_anisotropy = 2`` is the
    slender-body value.  :meth:`resistive` gives the swimming study's medium.

    ``mode="swimming"``: the swimmers move through a fluid of density
    ``fluid_density_kg_m3`` described by MuJoCo's ellipsoid fluid model
    (quadratic drag, far larger across a link than along it, plus added
    mass and lift), on top of the isotropic linear drag ``c``.  The
    anisotropy makes a lone swimmer advance head first (toward -x);
    :meth:`swimming` gives water with ``c = 0.1 N s/m``.
    """

    drag_N_s_per_m: float = 2.0
    """c: linear drag coefficient per link, N s / m (``mode="resistive"``: the tangential one, c_par)."""
    mode: str = "viscous"
    """``"viscous"`` (isotropic, no locomotion), ``"resistive"`` (resistive-force drag) or
    ``"swimming"`` (MuJoCo's ellipsoid fluid model)."""
    fluid_density_kg_m3: float = 1000.0
    """Fluid density for ``mode="swimming"``, kg / m^3 (ignored otherwise)."""
    drag_anisotropy: float = 2.0
    """c_perp / c_par for ``mode="resistive"`` (>= 1; 1 is isotropic; ignored otherwise)."""

    def __post_init__(self):
        _positive("drag_N_s_per_m", self.drag_N_s_per_m, "N s/m")
        if self.mode not in GROUND_MODES:
            raise ParameterError("mode", "'viscous', 'resistive' or 'swimming'", self.mode)
        _positive("fluid_density_kg_m3", self.fluid_density_kg_m3, "kg/m^3")
        if _finite("drag_anisotropy", self.drag_anisotropy) < 1.0:
            raise ParameterError("drag_anisotropy", ">= 1 (c_perp / c_par; 1 is isotropic)", self.drag_anisotropy)

    @property
    def normal_drag_N_s_per_m(self) -> float:
        """c_perp = ``drag_anisotropy * drag_N_s_per_m``: the resistive medium's drag per link across it, N s/m."""
        return self.drag_anisotropy * self.drag_N_s_per_m

    @classmethod
    def swimming(cls, fluid_density_kg_m3: float = 1000.0, drag_N_s_per_m: float = 0.1) -> "Ground":
        """MuJoCo's ellipsoid fluid model in a water-like fluid plus a weak linear drag."""
        return cls(drag_N_s_per_m=drag_N_s_per_m, mode="swimming", fluid_density_kg_m3=fluid_density_kg_m3)

    @classmethod
    def resistive(cls, drag_N_s_per_m: float = 2.0, drag_anisotropy: float = 2.0) -> "Ground":
        """The swimming study's viscous medium: resistive-force drag with ``c_par`` = the table's
        isotropic drag per link (2 N s/m), so the only change from the non-swimming model is the
        anisotropy, and ``c_perp / c_par = 2``, the slender-body value."""
        return cls(drag_N_s_per_m=drag_N_s_per_m, mode="resistive", drag_anisotropy=drag_anisotropy)


GROUND_MODES = ("viscous", "resistive", "swimming")
"""The :attr:`Ground.mode` values."""


@dataclass(frozen=True)
class Channel(_Params):
    """Two rigid walls parallel to x at ``y = +-width_m/2``.

    ``end_walls_m``: if set, two more walls at ``x = +-end_walls_m/2``
    (the packing study's short channel, 1.1 L).
    """

    width_m: float = 0.13
    """W: wall-to-wall separation, m (the paper's confinement d is the wall distance per swimmer side by
    side, so a pair's W = 2 d: :func:`undulate.theory.channel_width_m`)."""
    length_m: float = 1.2
    """Channel length, m (walls are drawn this long; >= 1 m)."""
    end_walls_m: float | None = None
    """Longitudinal distance between end walls, m, or None (open ends)."""

    def __post_init__(self):
        _positive("width_m", self.width_m, "m")
        ln = _positive("length_m", self.length_m, "m")
        if ln < 1.0:
            raise ParameterError("length_m", ">= 1 m", self.length_m)
        if self.end_walls_m is not None:
            _positive("end_walls_m", self.end_walls_m, "m")


@dataclass(frozen=True)
class ContactModel(_Params):
    """Frictionless normal contact (MuJoCo soft constraint).

    ``solref = (timeconst_s, dampratio)``, ``solimp = (dmin, dmax, width_m)``.
    The default time constant is two time steps, the stiffest MuJoCo's
    implicit constraint model keeps stable.  Contacts exist only from the
    step at which bodies overlap, so a body arriving at speed ``v`` is up to
    ``v dt`` deep before any contact force acts; the time-step rule
    (:func:`undulate.scene.auto_timestep`) keeps ``v_max dt <=
    target_penetration_m`` in any scene where bodies can touch.  The soft constraint's regularisation uses MuJoCo's exact
    Delassus diagonal (``mjENBL_DIAGEXACT``; the default approximation from
    body weights at the straight pose made jammed contacts softer than
    ``solref``/``solimp`` say).  Measured (docs/contact.md,
    tests/test_simulation.py): steady interpenetration < 1 mm and start-up
    < 2 mm for pairs and for jammed 50-swimmer packs.
    """

    timeconst_s: float | None = None
    """Contact restitution time constant, s (None: two time steps)."""
    dampratio: float = 1.0
    """Contact damping ratio (1 = critical)."""
    dmin: float = 0.95
    dmax: float = 0.99
    width_m: float = 0.001
    """Impedance transition width, m."""
    margin_m: float = 0.0
    """Contact detection margin, m."""
    max_penetration_m: float = 0.0075
    """Interpenetration beyond this stops the run as diverged, m (default:
    half the default body width: the bodies are passing through each other)."""
    target_penetration_m: float = 0.001
    """Penetration the automatic time step allows one impact at the fastest
    approach speed, m (see the class docstring)."""

    def __post_init__(self):
        if self.timeconst_s is not None:
            _positive("timeconst_s", self.timeconst_s, "s")
        _positive("dampratio", self.dampratio)
        for n in ("dmin", "dmax"):
            v = _finite(n, getattr(self, n))
            if not 0 < v < 1:
                raise ParameterError(n, "in (0, 1)", v)
        _positive("width_m", self.width_m, "m")
        _nonneg("margin_m", self.margin_m, "m")
        _positive("max_penetration_m", self.max_penetration_m, "m")
        _positive("target_penetration_m", self.target_penetration_m, "m")


CONTROLLER_KINDS = ("open-loop", "self-oscillating", "phase-oscillator", "relay")


@dataclass(frozen=True)
class ControllerParams(_Params):
    """Which gait controller drives the servos, and its parameters.

    The equations, units and references are in :mod:`undulate.control`.
    ``open-loop`` (default) is the paper's travelling wave, stepped exactly
    as before; the closed-loop kinds read each swimmer's joint angles,
    speeds and servo torques every ``1 / control_rate_hz`` and set the
    servos' targets, with MuJoCo stepping in C in between.
    """

    kind: str = "open-loop"
    """``"open-loop"``, ``"self-oscillating"``, ``"phase-oscillator"`` or ``"relay"``."""
    control_rate_hz: float = 100.0
    """Control (servo-bus) rate, Hz: sensing and new targets this often.  The
    control period is rounded to a whole number of integrator steps; the
    dataset records the rate used (attr ``control_rate``)."""
    coupling: float = 0.0
    """``phase-oscillator``: load-feedback strength sigma, rad/s per N m (>= 0)."""
    arrival_fraction: float = 0.9
    """``self-oscillating``: a turning point counts as reached once the measured
    joint angle is this fraction of beta on its side, in (0, 1]."""
    max_hold_s: float | None = None
    """``self-oscillating``: a joint stalled at its turning point releases it after
    this long, s (None: a quarter period)."""
    stall_speed_rad_s: float = 0.2
    """``self-oscillating``: below this measured speed a held joint counts as stalled, rad/s."""
    reverse_error_rad: float = 0.1
    """``relay``: a joint lagging its command by more than this, against the commanded motion,
    is blocked and its drive reverses, rad (> 0)."""
    reverse_rate_factor: float = 4.0
    """``relay``: the phase runs this many times faster than 2 pi f while the drive reverses (> 1)."""

    def __post_init__(self):
        if self.kind not in CONTROLLER_KINDS:
            raise ParameterError("controller", "one of " + ", ".join(CONTROLLER_KINDS), self.kind)
        rate = _positive("control_rate_hz", self.control_rate_hz, "Hz")
        if rate > 10000:
            raise ParameterError("control_rate_hz", "in (0, 10000] Hz", self.control_rate_hz)
        object.__setattr__(self, "control_rate_hz", rate)
        object.__setattr__(self, "coupling", _nonneg("coupling", self.coupling, "rad/s per N m"))
        a = _positive("arrival_fraction", self.arrival_fraction)
        if a > 1:
            raise ParameterError("arrival_fraction", "in (0, 1]", self.arrival_fraction)
        if self.max_hold_s is not None:
            _positive("max_hold_s", self.max_hold_s, "s")
        _positive("stall_speed_rad_s", self.stall_speed_rad_s, "rad/s")
        _positive("reverse_error_rad", self.reverse_error_rad, "rad")
        if not _finite("reverse_rate_factor", self.reverse_rate_factor) > 1:
            raise ParameterError("reverse_rate_factor", "a number > 1", self.reverse_rate_factor)

    @property
    def closed_loop(self) -> bool:
        return self.kind != "open-loop"


MAX_GROUP_EXTENT_M = 1e6
"""The largest initial longitudinal extent of a group (the span of the swimmers' starting x), m.  The
group is centred on x = 0, so its swimmers start within 5e5 m of it, where float64 positions are
spaced at most 5.8e-11 m.  At dx0 = 1e20 m (swimmers at +-5e19 m) the spacing was 8.2e3 m: a
swimmer's own links, a few cm apart, overlapped, and the run stopped as diverged, its diagnosis
blaming the time step."""


@dataclass(frozen=True)
class Scene(_Params):
    """Swimmers side by side in a channel.

    Swimmers start straight (all joint angles 0), stacked from low to high
    ``y`` in the order of ``phases_rad``, centre lines ``width + lateral_gap_m``
    apart and the stack centred in the channel.  Swimmer ``j`` starts
    ``dx0_m[j-1]`` further along ``x`` than swimmer ``j-1`` (the group is
    centred on x = 0).  ``forces_N[j]`` is a constant longitudinal force (+x)
    on swimmer ``j``, spread equally over its links.
    """

    phases_rad: tuple[float, ...] = (0.0, 0.0)
    """phi_j per swimmer, rad.  Their count is the number of swimmers."""
    gait: Gait = field(default_factory=Gait)
    geometry: SwimmerGeometry = field(default_factory=SwimmerGeometry)
    servo: Servo = field(default_factory=Servo)
    ground: Ground = field(default_factory=Ground)
    channel: Channel = field(default_factory=Channel)
    contact: ContactModel = field(default_factory=ContactModel)
    dx0_m: tuple[float, ...] | float = 0.0
    """Initial longitudinal offset of each swimmer from the previous one, m
    (a scalar applies to every neighbouring pair)."""
    lateral_gap_m: float = 0.0
    """Initial gap between neighbouring bodies, m (0 = laterally in contact,
    centre lines ``w`` apart)."""
    forces_N: tuple[float, ...] | None = None
    """Constant longitudinal force on each swimmer, N (+x), or None."""
    force_onset_s: float = 0.0
    """Time at which ``forces_N`` switch on, s (they stay on until ``force_offset_s``)."""
    force_offset_s: float | None = None
    """Time at which ``forces_N`` switch off again, s (> ``force_onset_s``), or None: they stay on to the
    end.  The potential study's release runs remove the force to see the pair go back (paper Sec. III.G:
    the displaced position "was sustained until the force was removed")."""
    controller: ControllerParams = field(default_factory=ControllerParams)
    """The gait controller (default: the paper's open-loop travelling wave)."""
    hold_x: bool = False
    """Lock each swimmer's longitudinal position (its body midpoint's x): the
    swimmer has no x degree of freedom; lateral motion and rotation stay free."""
    heading_guide: bool = False
    """Remove the yaw recoil: a stiff PD actuator on each swimmer's root yaw joint
    (:data:`undulate.scene.HEADING_GUIDE_KP_NM_PER_RAD`) holds the heading at
    which the commanded body shape's head-to-tail chord lies along the channel
    (x).  On isotropic drag a free body turns back and forth as it bends (the
    chord swings by +-0.10-0.13 rad), which adds a standing wave to its
    lab-frame shape; with the guide the lab-frame shape is the commanded
    travelling wave, the body the compatibility model assumes.  Lateral and
    longitudinal motion stay free.  Open-loop gait only.  A model the
    sensitivity study uses to test the link-number claim, not the default."""

    def __post_init__(self):
        for name, kind in (("gait", Gait), ("geometry", SwimmerGeometry), ("servo", Servo), ("ground", Ground),
                           ("channel", Channel), ("contact", ContactModel), ("controller", ControllerParams)):
            if not isinstance(getattr(self, name), kind):
                raise ParameterError(name, f"a {kind.__name__}", getattr(self, name))
        phases = _finite_values("phases_rad", self.phases_rad, "a sequence of finite numbers (rad)")
        if len(phases) < 1 or len(phases) > 500:
            raise ParameterError("phases_rad", "1 to 500 values, one per swimmer", self.phases_rad)
        object.__setattr__(self, "phases_rad", phases)
        n = len(phases)
        allowed = f"a finite scalar or {n - 1} finite values (one per neighbouring pair), m"
        dx0 = _finite_values("dx0_m", self.dx0_m, allowed)
        if np.ndim(self.dx0_m) == 0:
            dx0 = dx0 * (n - 1)
        if len(dx0) != n - 1:
            raise ParameterError("dx0_m", allowed, self.dx0_m)
        xs = np.concatenate([[0.0], np.cumsum(dx0)])
        if float(np.ptp(xs)) > MAX_GROUP_EXTENT_M:
            raise ParameterError("dx0_m", f"offsets whose sum spans at most {MAX_GROUP_EXTENT_M:g} m (farther out, "
                                 "float64 positions no longer resolve a body's links)", self.dx0_m)
        object.__setattr__(self, "dx0_m", dx0)
        gap = _nonneg("lateral_gap_m", self.lateral_gap_m, "m")
        _nonneg("force_onset_s", self.force_onset_s, "s")
        if self.force_offset_s is not None:
            off = _finite("force_offset_s", self.force_offset_s)
            if not off > self.force_onset_s:
                raise ParameterError("force_offset_s", f"None or a time > force_onset_s ({self.force_onset_s:g} s)",
                                     self.force_offset_s)
            object.__setattr__(self, "force_offset_s", off)
        object.__setattr__(self, "hold_x", _flag("hold_x", self.hold_x))
        object.__setattr__(self, "heading_guide", _flag("heading_guide", self.heading_guide))
        if self.heading_guide and self.controller.closed_loop:
            raise ParameterError("heading_guide", "False with a closed-loop controller (the guide follows the "
                                 "open-loop gait's commanded shape)", self.heading_guide)
        if self.forces_N is not None:
            allowed = f"{n} finite values, one per swimmer (N)"
            forces = _finite_values("forces_N", self.forces_N, allowed)
            if np.ndim(self.forces_N) == 0 or len(forces) != n:
                raise ParameterError("forces_N", allowed, self.forces_N)
            object.__setattr__(self, "forces_N", forces)
        w = self.geometry.width_m
        stack = n * w + (n - 1) * gap
        if stack >= self.channel.width_m:
            raise ParameterError(
                "channel width",
                f"> {stack:g} m to fit {n} swimmer(s) of width {w:g} m side by side",
                self.channel.width_m,
            )
        if self.channel.end_walls_m is not None:
            xs = self.initial_x_m()
            half = self.channel.end_walls_m / 2
            L = self.geometry.length_m
            if np.any(xs - L / 2 <= -half) or np.any(xs + L / 2 >= half):
                raise ParameterError(
                    "channel end_walls_m",
                    f"longer than the swimmers' longitudinal extent ({float(np.ptp(xs)) + L:g} m)",
                    self.channel.end_walls_m,
                )

    @property
    def n_swimmers(self) -> int:
        return len(self.phases_rad)

    @property
    def wavelength_m(self) -> float:
        """lambda = L / xi, m (inf for the standing wave)."""
        return self.gait.wavelength_m(self.geometry.length_m)

    def initial_x_m(self) -> np.ndarray:
        """Initial centre x of each swimmer, m (group centred on x = 0)."""
        xs = np.concatenate([[0.0], np.cumsum(self.dx0_m)])
        return xs - 0.5 * (xs.max() + xs.min())

    def initial_y_m(self) -> np.ndarray:
        """Initial centre-line y of each swimmer, m (stack centred in the channel)."""
        pitch = self.geometry.width_m + self.lateral_gap_m
        ys = pitch * np.arange(self.n_swimmers)
        return ys - ys.mean()


_NESTED = {
    ("Scene", "gait"): Gait,
    ("Scene", "geometry"): SwimmerGeometry,
    ("Scene", "servo"): Servo,
    ("Scene", "ground"): Ground,
    ("Scene", "channel"): Channel,
    ("Scene", "contact"): ContactModel,
    ("Scene", "controller"): ControllerParams,
}


@dataclass(frozen=True)
class SimOptions(_Params):
    """How to integrate and what to record."""

    duration_s: float = 30.0
    """Simulated time, s (> 0)."""
    timestep_s: float | None = None
    """Integrator time step, s, or None (default) for the step the model needs:
    :func:`undulate.scene.auto_timestep` derives it from the compiled swimmer
    (the fastest servo mode, ``omega dt <= 0.5``, capped at 2 ms; 2 ms for the
    paper's 3-link swimmer, 0.25 ms for 12 links).  An explicit value overrides
    it; allowed (0, 0.004] (larger steps are unstable with the servo and
    contact stiffness).  The dataset records the step used (attr ``timestep``)."""
    sample_rate_hz: float = 20.0
    """Recording rate, Hz (<= 1/timestep)."""
    chunk_steps: int = 2000
    """Steps per call into ``mujoco.rollout`` (bounds memory)."""
    solver: str = "auto"
    """Constraint solver: ``"auto"`` (Newton at every scene size: with the
    pinned MuJoCo 3.17.0 its sparse-Jacobian path, used from 60 degrees of
    freedom, agrees with dense Newton on jammed 50-swimmer packs and is the
    cheapest correct solver there; MuJoCo 4.0.0's is wrong, see
    docs/contact.md), ``"newton"``, ``"cg"`` or ``"pgs"``."""
    integrator: str = "implicitfast"
    """``"implicitfast"`` (default: first order, implicit in the servo and
    contact damping) or ``"rk4"`` (fourth order, ~4x the cost).  The
    first-order scheme makes a lone swimmer's centre of mass creep by
    O(dt) (0.3 mm/s at dt = 2 ms, i.e. 0.1 % of L per period); RK4 removes
    it (tests/test_simulation.py)."""

    backend: str | None = None
    """Which engine steps the scenes: ``"mujoco"`` (MuJoCo's C engine through
    ``mujoco.rollout``, float64, on the CPU) or ``"warp"`` (MuJoCo Warp: every
    scene of a batch is one world of one model, float32, on a GPU or on Warp's
    CPU device; the ``gpu`` extra).  None: the settings in effect
    (:attr:`undulate.execution.Execution.backend`: the ``execution=`` a study or sweep
    was given, the CLI's ``--backend``, or ``UNDULATE_BACKEND``; else ``"mujoco"``).  The dataset
    records the one used (attrs ``backend``, ``device``, ``precision``; ``engine`` and
    ``engine_requested`` where a run asked of Warp steps on MuJoCo)."""
    device: str | None = None
    """The Warp backend's device: ``"cuda"`` or ``"cpu"`` (None: the settings in effect,
    :attr:`undulate.execution.Execution.device`, else ``"cuda"`` where there is one).  Left out
    for the ``"mujoco"`` backend, which steps on the CPU."""

    record: tuple[str, ...] | None = None
    """Variables to record (names of :data:`undulate.schema.RECORDABLE`), or
    None for all.  Recording fewer saves memory and file size; without
    ``"contact_force_pair"`` the swimmer-swimmer contact sensors are not built
    at all (each scans every contact every step)."""

    MAX_TIMESTEP_S = 0.004
    RECORDABLE = _schema.RECORDABLE
    BACKENDS = ("mujoco", "warp")

    @property
    def recorded(self) -> tuple[str, ...]:
        """The variables this run records, in the dataset's order."""
        return self.RECORDABLE if self.record is None else tuple(v for v in self.RECORDABLE if v in self.record)

    def __post_init__(self):
        _positive("duration_s", self.duration_s, "s")
        sr = _positive("sample_rate_hz", self.sample_rate_hz, "Hz")
        if self.timestep_s is not None:
            dt = _positive("timestep_s", self.timestep_s, "s")
            if dt > self.MAX_TIMESTEP_S:
                raise ParameterError("timestep_s", f"in (0, {self.MAX_TIMESTEP_S}] s for a stable simulation",
                                     self.timestep_s)
            object.__setattr__(self, "timestep_s", dt)
            if sr > 1.0 / dt * (1 + 1e-9):
                raise ParameterError("sample_rate_hz", f"<= 1/timestep = {1 / dt:g} Hz", self.sample_rate_hz)
            if self.duration_s < dt:
                raise ParameterError("duration_s", f">= one time step ({dt:g} s)", self.duration_s)
        if self.solver not in ("auto", "newton", "cg", "pgs"):
            raise ParameterError("solver", "'auto', 'newton', 'cg' or 'pgs'", self.solver)
        if self.integrator not in ("implicitfast", "rk4"):
            raise ParameterError("integrator", "'implicitfast' or 'rk4'", self.integrator)
        if self.backend not in (None, *self.BACKENDS):
            raise ParameterError("backend", "'mujoco' or 'warp' (or None: the session's default)", self.backend)
        if self.device not in (None, "cpu", "cuda"):
            raise ParameterError("device", "'cuda' or 'cpu' (or None: the default)", self.device)
        if self.device is not None and self.backend == "mujoco":
            raise ParameterError("device", "left out with backend 'mujoco' (it steps on the CPU)", self.device)
        if self.record is not None:
            try:
                rec = (self.record,) if isinstance(self.record, str) else tuple(self.record)
            except TypeError:  # not a name or a sequence of names
                raise ParameterError("record", "a non-empty subset of " + ", ".join(self.RECORDABLE),
                                     self.record) from None
            bad = [v for v in rec if v not in self.RECORDABLE]
            if bad or not rec:
                raise ParameterError("record", "a non-empty subset of " + ", ".join(self.RECORDABLE), self.record)
            object.__setattr__(self, "record", rec)
        try:
            whole = (not isinstance(self.chunk_steps, bool) and int(self.chunk_steps) == self.chunk_steps
                     and self.chunk_steps >= 1)
        except (TypeError, ValueError, OverflowError):
            whole = False
        if not whole:
            raise ParameterError("chunk_steps", "a positive integer", self.chunk_steps)

    def with_timestep(self, timestep_s: float) -> "SimOptions":
        """A copy with the time step set (validated as an explicit step)."""
        return dataclasses.replace(self, timestep_s=float(timestep_s))

    def _dt(self) -> float:
        if self.timestep_s is None:
            raise ParameterError("timestep_s", "resolved before counting steps "
                                 "(undulate.simulation.resolve_options)", None)
        return self.timestep_s

    @property
    def n_steps(self) -> int:
        """Number of integrator steps (needs a resolved ``timestep_s``)."""
        return int(round(self.duration_s / self._dt()))

    @property
    def steps_per_sample(self) -> int:
        """Integrator steps per recorded sample (needs a resolved ``timestep_s``)."""
        return max(1, int(round(1.0 / (self.sample_rate_hz * self._dt()))))
