"""Build the MuJoCo model of swimmers in a channel (build, never run).

One swimmer is defined once (:func:`swimmer_spec`) and attached N times
under the name prefixes ``s0_``, ``s1_``, ... (:func:`scene_spec`).  The
compiled model comes with a :class:`SceneIndex` that resolves every name to
its address once, so nothing downstream indexes arrays by position.

Model choices (documented here, tested in ``tests/``):

* **Planar bodies.**  Each swimmer's middle link (the one holding the
  body's midpoint) carries three root degrees of freedom (slide x, slide y,
  hinge z) with their frame at the midpoint; the other links hang from it
  toward the head and toward the tail through hinge-z joints
  ``j0..j{N-2}`` (joint ``i`` measures link ``i+1`` relative to link ``i``
  whichever way the chain runs).  Rooting at the midpoint keeps a lone
  swimmer's centre of mass still under the first-order integrator
  (:func:`swimmer_spec`).  No gravity (the plane is horizontal and its
  support is modelled by the ground drag alone).  Heads point to -x.
* **Mass and inertia** are those of a solid box ``l x w x h`` per link,
  ``l = L/N``, mass ``M/N``.
* **Collision geometry** is a capsule of radius ``w/2`` spanning the link's
  full length ``l``: its flanks coincide with the box's flanks, which is
  where lateral contact happens; only the link ends are rounded.  A capsule
  pair costs one analytic test instead of box-box clipping (see
  ``benchmarks/bench_simulate.py`` for the measured difference).
* **Contact** is frictionless (``condim=1``), normal force only, between
  links of different swimmers, between links and walls, and between
  non-adjacent links of one swimmer; adjacent links never collide
  (MuJoCo's parent-child filter).  Softness: :class:`~undulate.params.ContactModel`.
* **Walls** are planes: ``y = -d/2`` (normal +y), ``y = +d/2`` (normal -y)
  and optional end walls ``x = -E/2, +E/2``.
* **Swimming** (``Ground(mode="swimming")``): the link geoms switch to
  MuJoCo's ellipsoid fluid model at the given density (anisotropic
  quadratic drag, added mass, lift), computed in C like everything else.
* **Resistive medium** (``Ground(mode="resistive")``): linear drag per link
  along and across its own axis at its centre, and the rotational drag of a
  rod, expressed as drag actuators (:func:`_add_resistive_drag`,
  :func:`resistive_coefficients`); ``opt.viscosity`` is 0 there.
* **Ground drag** uses MuJoCo's inertia-box fluid model with zero density:
  each link feels ``F = -3 pi mu D v`` (``D`` = mean side of its inertia
  box, ``mu`` = ``opt.viscosity``) and a rotational drag
  ``-pi mu D^3 omega``.  ``mu`` is chosen so the linear coefficient equals
  :attr:`~undulate.params.Ground.drag_N_s_per_m`.  Equal links with equal
  drag make the swimmer's centre of mass exactly stationary under internal
  torques alone.
* **Servos** are MuJoCo ``pid`` actuators, inputs ``[pos, vel]``,
  ``forcerange = +-torque_limit``.
* **Perturbation**: ``motor`` actuators with site transmission apply
  ``F/N`` along world x at each link's centre of mass, the longitudinal force
  of :attr:`~undulate.params.Scene.forces_N` spread equally over the links
  (it translates the body without turning it).
* **Sensors** (all computed in C each step): each swimmer's centre of mass
  (``subtreecom``); the net contact force between neighbouring swimmers
  ``(j, j+1)`` (in the initial lateral order) and on each wall (lower,
  upper, end walls; one sensor per wall: per-swimmer wall sensors cost
  more than the physics for large groups); and the deepest interpenetration among all
  contacts.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from .errors import ParameterError
from .params import Scene

__all__ = ["SceneIndex", "resistive_coefficients", "CompiledScene", "swimmer_spec", "root_link", "root_offset_m", "scene_spec", "build", "servo_frequency_rad_s",
           "auto_timestep", "contact_possible", "approach_speed_m_s"]

_Q_ALONG_Y_UP = (math.sqrt(0.5), -math.sqrt(0.5), 0.0, 0.0)  # plane normal +y
_Q_ALONG_Y_DOWN = (math.sqrt(0.5), math.sqrt(0.5), 0.0, 0.0)  # plane normal -y
_Q_ALONG_X_UP = (math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0)  # plane normal +x
_Q_ALONG_X_DOWN = (math.sqrt(0.5), 0.0, -math.sqrt(0.5), 0.0)  # plane normal -x

_SWIMMER_RGBA = (0.85, 0.45, 0.2, 1.0)

HEADING_GUIDE_KP_NM_PER_RAD = 200.0
"""Stiffness of the heading guide (:attr:`~undulate.params.Scene.heading_guide`), N m/rad.  Stiff
against the drag torques it cancels (the default body's rotational drag is ~0.1 N m s/rad): guided
9-link pairs settle at the same offsets to 3e-4 L with 50, 200 and 800 N m/rad (3-link pairs at
dphi >= pi/2 may end on another branch)."""
HEADING_GUIDE_KV_NMS_PER_RAD = 4.0
"""Damping of the heading guide, N m s/rad (kp / 50)."""


def chord_heading(alpha: np.ndarray, alpha_dot: np.ndarray, n_links: int) -> tuple[np.ndarray, np.ndarray]:
    """The root yaw (rad) at which a body of joint angles ``alpha`` has its head-to-tail chord along x,
    and its rate (rad/s) for joint velocities ``alpha_dot`` (both ``(..., N-1)``).

    Link ``k`` points at ``yaw + c_k - c_r`` with ``c_k = alpha_0 + ... + alpha_{k-1}`` and ``r`` the
    root link; the links are equal, so the chord points along ``(sum cos, sum sin)`` of those angles
    and is along x when ``yaw = -atan2(S, C)``, ``S, C = sum_k sin, cos(c_k - c_r)``.
    """
    rl = root_link(n_links)
    zeros = np.zeros_like(alpha[..., :1])
    c = np.concatenate([zeros, np.cumsum(alpha, axis=-1)], axis=-1)
    cd = np.concatenate([zeros, np.cumsum(alpha_dot, axis=-1)], axis=-1)
    c, cd = c - c[..., rl:rl + 1], cd - cd[..., rl:rl + 1]
    S, C = np.sin(c).sum(-1), np.cos(c).sum(-1)
    dS, dC = (np.cos(c) * cd).sum(-1), (-np.sin(c) * cd).sum(-1)
    return -np.arctan2(S, C), -(C * dS - S * dC) / (S * S + C * C)
_WALL_RGBA = (0.5, 0.5, 0.55, 0.4)


def _timeconst(scene: Scene, timestep_s: float) -> float:
    """Contact time constant, s: the scene's, or two time steps by default."""
    tc = scene.contact.timeconst_s
    return 2.0 * timestep_s if tc is None else tc


def _contact_attrs(scene: Scene, timestep_s: float) -> dict:
    """Geom attributes of frictionless soft contact, shared by links and walls."""
    c = scene.contact
    return dict(condim=1, solref=[_timeconst(scene, timestep_s), c.dampratio],
                solimp=[c.dmin, c.dmax, c.width_m, 0.5, 2.0], margin=c.margin_m)


def drag_viscosity(scene: Scene) -> float:
    """MuJoCo ``opt.viscosity`` (Pa s) giving the per-link linear drag coefficient.

    MuJoCo's inertia-box model applies ``F = -3 pi mu D v`` to each body,
    with ``D`` the mean side of its equivalent inertia box, here the link box
    ``l x w x h``: ``mu = c / (3 pi D)``.
    """
    g = scene.geometry
    D = (g.link_length_m + g.width_m + g.height_m) / 3.0
    return scene.ground.drag_N_s_per_m / (3.0 * math.pi * D)


def root_link(n_links: int) -> int:
    """Index of the link that carries a swimmer's free (x, y, yaw) joints: the one holding the
    body's midpoint (odd N: the middle link; even N: the one just tail-side of the middle joint)."""
    return n_links // 2


def root_offset_m(scene: Scene) -> float:
    """Distance from the head tip to the root frame (the body's midpoint) of a straight body, m."""
    return scene.geometry.length_m / 2


def _root_frame_in_link(n_links: int, link_length_m: float) -> float:
    """Distance from the root link's head end to the root frame (the body's midpoint), m:
    ``l/2`` (its centre) for odd N, 0 (the middle joint) for even N."""
    return (n_links / 2 - root_link(n_links)) * link_length_m


def swimmer_spec(scene: Scene, timestep_s: float, *, push: bool | None = None,
                 servo: str = "pid") -> mujoco.MjSpec:
    """One swimmer (body along +x, root link centred at the origin) as an ``MjSpec``.

    Names (before the attach prefix): bodies ``link0..link{N-1}``, root
    joints ``x``, ``y``, ``yaw``, body joints ``j0..j{N-2}``, geoms
    ``g{k}`` (and ``g{k}_{s}`` for further collision segments), servos
    ``servo0..``, and, when ``push`` (default: ``scene.forces_N`` is set), the perturbation
    actuators ``push0..push{N-1}`` (a site transmission costs a Jacobian per
    actuator and step: in a 50-swimmer pack the 150 unused push actuators
    took 77 us of a ~600 us step).

    The free joints sit on the link holding the body's **midpoint**
    (:func:`root_link`), their frame at the midpoint (the middle link's
    centre for odd N, the middle joint for even N); the links toward the
    tail hang from it as a chain, and so do the links toward the head.  Joint ``i`` always measures
    ``alpha_i``, the angle of link ``i+1`` relative to link ``i``
    (counter-clockwise about +z): head-side joints turn about -z because
    their child is the head-side link.  Rooting at the middle matters for
    the integrator: with semi-implicit Euler the centre of mass of a body
    rooted at its head creeps by O(dt) (0.28 mm/s at 2 ms: the position
    update is first order on a configuration space whose centre of mass is
    curved in the joint angles); rooted at the midpoint the curvature terms of
    the two half-chains cancel and a lone swimmer stays put to 1e-4 mm/s
    (tests/test_simulation.py).

    The perturbation force (:attr:`~undulate.params.Scene.forces_N`) is
    spread equally over the links: actuators ``push0..`` apply ``F/N`` along
    world x at each link's centre of mass (sites ``c0..``), so it
    translates the body without turning it.
    """
    spec = mujoco.MjSpec()
    _build_links(spec.worldbody, scene, timestep_s)
    _add_servos(spec, scene, servo)
    if scene.ground.mode == "resistive":
        _add_resistive_drag(spec, scene)
    # the perturbation force, spread equally over the links: F/N along world x at each link's centre
    if not (scene.forces_N is not None if push is None else push):
        return spec
    spec.worldbody.add_site(name="ref")
    for k in range(scene.geometry.n_links):
        push = spec.add_actuator(name=f"push{k}", target=f"c{k}", trntype=mujoco.mjtTrn.mjTRN_SITE, refsite="ref")
        push.set_to_motor()
    return spec


def _build_links(world, scene: Scene, timestep_s: float) -> None:
    """The root link under ``world``, then the chains toward the tail and toward the head."""
    g = scene.geometry
    n, l = g.n_links, g.link_length_m
    rl = root_link(n)
    a_mid = _root_frame_in_link(n, l)
    root = _add_link(world, scene, timestep_s, a_mid, rl, 0.0, +1, None, 1.0)
    parent, pos = root, l - a_mid
    for k in range(rl + 1, n):  # toward the tail: joint k-1 in link k, alpha_{k-1} about +z
        parent, pos = _add_link(parent, scene, timestep_s, a_mid, k, pos, +1, f"j{k - 1}", 1.0), l
    parent, pos = root, -a_mid
    for k in range(rl - 1, -1, -1):  # toward the head: joint k in link k, link k turns by -alpha_k
        parent, pos = _add_link(parent, scene, timestep_s, a_mid, k, pos, -1, f"j{k}", -1.0), -l


def _add_link(parent, scene: Scene, timestep_s: float, a_mid: float, k: int, pos: float, sign: float,
              joint: str | None, axis_z: float):
    """Link ``k`` spanning ``[0, sign * l]`` from its frame (``+1``: toward the tail); the root link
    (``joint`` None) has its frame at the body's midpoint, ``a_mid`` behind its head end."""
    g, sv = scene.geometry, scene.servo
    l = g.link_length_m
    body = parent.add_body(name=f"link{k}", pos=[pos, 0, 0])
    body.explicitinertial = True  # inertia of the box link, centred on the link's midpoint
    body.mass = g.link_mass_kg
    lo = 0.0 if sign > 0 else -l  # the link spans [lo, lo + l] along the body frame's x
    if joint is None:  # the root link: frame at the body's midpoint
        lo = -a_mid
    body.ipos = [lo + l / 2, 0, 0]
    body.add_site(name=f"c{k}", pos=[lo + l / 2, 0, 0])  # where the perturbation force acts
    body.inertia = list(g.link_inertia_kg_m2)
    if joint is None:
        if not scene.hold_x:  # Scene.hold_x: no longitudinal degree of freedom
            body.add_joint(name="x", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[1, 0, 0])
        body.add_joint(name="y", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 1, 0])
        body.add_joint(name="yaw", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
    else:
        # the motor's back-EMF: a damping outside the servo's saturation (Servo.back_emf)
        body.add_joint(name=joint, type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, axis_z],
                       damping=sv.back_emf_Nms_per_rad)
    _add_link_geoms(body, scene, timestep_s, k, lo)
    return body


def _add_link_geoms(body, scene: Scene, timestep_s: float, k: int, lo: float) -> None:
    """The collision geoms of link ``k`` (spanning ``[lo, lo + l]``), and its fluid geom when needed."""
    g = scene.geometry
    l, r = g.link_length_m, g.width_m / 2
    swimming = scene.ground.mode == "swimming"
    if g.collision_shape == "capsule":
        # capsules whose segments tile [lo + r, lo + l - r]: their union is the one capsule
        ends = np.linspace(lo + r, lo + l - r, g.collision_segments + 1)
        shapes = [dict(type=mujoco.mjtGeom.mjGEOM_CAPSULE, fromto=[a, 0, 0, b, 0, 0], size=[r, 0, 0])
                  for a, b in zip(ends[:-1], ends[1:])]
    else:
        shapes = [dict(type=mujoco.mjtGeom.mjGEOM_BOX, pos=[lo + l / 2, 0, 0], size=[l / 2, r, g.height_m / 2])]
    for s_i, shape in enumerate(shapes):
        body.add_geom(
            name=f"g{k}" if s_i == 0 else f"g{k}_{s_i}",
            **shape,
            **_contact_attrs(scene, timestep_s),
            contype=1,
            conaffinity=1,
            rgba=list(_SWIMMER_RGBA),
            mass=0,  # inertia is explicit
            fluid_ellipsoid=1 if (swimming and len(shapes) == 1) else 0,
        )
    if swimming and len(shapes) > 1:  # the fluid model sees the whole link: one non-colliding capsule
        body.add_geom(name=f"g{k}_fluid", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                      fromto=[lo + r, 0, 0, lo + l - r, 0, 0], size=[r, 0, 0], contype=0, conaffinity=0,
                      group=3, mass=0, fluid_ellipsoid=1)


RESISTIVE_AXES = (("par", (1, 0, 0, 0, 0, 0)), ("perp", (0, 1, 0, 0, 0, 0)), ("rot", (0, 0, 0, 0, 0, 1)))
"""The resistive medium's drag actuators per link (name suffix, gear in the link's centre-site frame):
along the link's axis, across it (in the plane) and about the plane normal."""


def resistive_coefficients(scene: Scene) -> tuple[float, float, float]:
    """``(c_par, c_perp, c_rot)`` of each link in the resistive medium: N s/m, N s/m, N m s/rad.

    ``c_par``, ``c_perp`` per link (:class:`~undulate.params.Ground`); the rotational drag of a rod of
    length ``l`` about its centre whose elements feel ``c_perp / l`` per unit length across it:
    ``c_rot = integral (c_perp / l) s^2 ds over [-l/2, l/2] = c_perp l^2 / 12``.
    """
    gr, l = scene.ground, scene.geometry.link_length_m
    c_perp = gr.normal_drag_N_s_per_m
    return gr.drag_N_s_per_m, c_perp, c_perp * l * l / 12.0


def _add_resistive_drag(spec: mujoco.MjSpec, scene: Scene) -> None:
    """Resistive-force drag on every link, computed by MuJoCo each step: three ``general`` actuators per
    link, ``drag{k}_par``, ``drag{k}_perp``, ``drag{k}_rot``, each a site transmission at the link's
    centre site ``c{k}`` (no refsite) with gear :data:`RESISTIVE_AXES`.  Such an actuator's velocity is
    the site's velocity along its gear axis in the site's (the link's) frame, and its force is applied
    along that axis at the site; with gain 0 and affine bias ``(0, 0, -c)`` the force is ``-c`` times
    that velocity, whatever the control input (the inputs stay 0).  A velocity-affine bias enters
    ``qDeriv``, so the implicitfast integrator treats the drag implicitly as it does joint damping
    (tests/test_resistive.py measures the forces against the closed form)."""
    coef = dict(zip(("par", "perp", "rot"), resistive_coefficients(scene)))
    for k in range(scene.geometry.n_links):
        for axis, gear in RESISTIVE_AXES:
            a = spec.add_actuator(name=f"drag{k}_{axis}", target=f"c{k}", trntype=mujoco.mjtTrn.mjTRN_SITE,
                                  gear=list(gear))
            a.gaintype = mujoco.mjtGain.mjGAIN_FIXED
            a.biastype = mujoco.mjtBias.mjBIAS_AFFINE
            a.gainprm[0] = 0.0
            a.biasprm[:3] = [0.0, 0.0, -coef[axis]]


SERVO_MODELS = ("pid", "affine")
"""How a servo is expressed in MuJoCo: ``"pid"`` (default; MuJoCo's ``pid`` actuator, inputs
``[pos, vel]``, the set-point slew-limited inside it) or ``"affine"`` (a position actuator with
velocity gain: force ``kp u - kp q - kv qdot``, one input ``u = q* + (kv / kp) qdot*``, the set-point
``q*`` slew-limited by the caller).  With no integral term the two give the same force; MuJoCo Warp
(:mod:`undulate.simulation._warp`) has no ``pid`` actuator and steps the affine one."""


def _add_servos(spec: mujoco.MjSpec, scene: Scene, servo: str = "pid") -> None:
    """A position servo on every body joint (``servo``: :data:`SERVO_MODELS`), and the heading guide's
    actuator if the scene has one."""
    sv = scene.servo
    if servo not in SERVO_MODELS:
        raise ValueError(f"servo model {servo!r} (allowed: {SERVO_MODELS})")

    def add(a, kp, kv, ki=-1.0, imax=-1.0, slewmax=-1.0):
        if servo == "pid":
            a.set_to_pid(kp=kp, kv=kv, ki=ki, imax=imax, slewmax=slewmax)
        else:
            a.set_to_position(kp=kp, kv=kv)

    for i in range(scene.geometry.n_links - 1):
        a = spec.add_actuator(name=f"servo{i}", target=f"j{i}", trntype=mujoco.mjtTrn.mjTRN_JOINT)
        add(a, sv.kp_Nm_per_rad, sv.kd_Nms_per_rad,
            ki=sv.ki_Nm_per_rad_s if sv.ki_Nm_per_rad_s > 0 else -1,
            imax=sv.integral_limit_rad_s if sv.ki_Nm_per_rad_s > 0 else -1,
            slewmax=sv.max_speed_rad_s if sv.max_speed_rad_s > 0 else -1)
        a.forcelimited = True
        a.forcerange = [-sv.torque_limit_Nm, sv.torque_limit_Nm]
    if scene.heading_guide:  # Scene.heading_guide: a stiff PD actuator on the root yaw (set-point, rate)
        a = spec.add_actuator(name="headguide", target="yaw", trntype=mujoco.mjtTrn.mjTRN_JOINT)
        add(a, HEADING_GUIDE_KP_NM_PER_RAD, HEADING_GUIDE_KV_NMS_PER_RAD)


MAX_AUTO_TIMESTEP_S = 0.002
"""Largest step :func:`auto_timestep` chooses, s (the paper's 3-link swimmer)."""
SERVO_STEP_FRACTION = 0.5
"""``omega_servo * dt`` that :func:`auto_timestep` allows (rad)."""


def _joint_inverse_inertia(scene: Scene) -> float:
    """``max_i (M^-1)_ii`` over the actuated joints of one free swimmer, 1/(kg m^2).  A swimmer's
    model does not depend on the gait phases (they enter only its controls and the scene's
    placement), so scenes that differ only in them share one computation (a sweep over phase lags
    compiles it once, not once a run: ~1 ms)."""
    return _joint_inverse_inertia_of(dataclasses.replace(scene, phases_rad=(0.0,) * len(scene.phases_rad)))


@functools.lru_cache(maxsize=256)
def _joint_inverse_inertia_of(scene: Scene) -> float:
    m = swimmer_spec(scene, MAX_AUTO_TIMESTEP_S).compile()
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    hinges = scene.geometry.n_links - 1  # the last dofs, after the root's (x, y, yaw; y, yaw with hold_x)
    return float(np.diag(np.linalg.inv(M))[m.nv - hinges:].max())


def servo_damping_rate_per_s(scene: Scene) -> float:
    """Fastest decay rate of a servo joint's damping, 1/s: ``(kd + b) max_i (M^-1)_ii``
    (``b`` the back-EMF).  Only explicit integrators (``rk4``) must resolve it."""
    sv = scene.servo
    return (sv.kd_Nms_per_rad + sv.back_emf_Nms_per_rad) * _joint_inverse_inertia(scene)


def servo_frequency_rad_s(scene: Scene) -> float:
    """Natural frequency of the fastest servo mode of one free swimmer, rad/s.

    ``omega = max_i sqrt(kp (M^-1)_ii)`` over the actuated joints, with
    ``M`` the swimmer's mass matrix in the straight pose (all other degrees
    of freedom free: the smallest effective inertia a servo drives).  It
    grows like ``N^1.5`` with the link count (link inertia ``~ N^-3``).
    """
    return float(np.sqrt(scene.servo.kp_Nm_per_rad * _joint_inverse_inertia(scene)))


def contact_possible(scene: Scene) -> bool:
    """Whether bodies of ``scene`` can touch: two or more swimmers, end walls,
    or side walls closer than half a body length to the centre line."""
    ch = scene.channel
    return scene.n_swimmers > 1 or ch.end_walls_m is not None or ch.width_m < scene.geometry.length_m


def approach_speed_m_s(scene: Scene) -> float:
    """Fastest speed at which a link can strike another body, m/s: the far end
    of a link turned at the servo's top speed (its set-point slew limit; if
    unlimited, twice the gait's peak joint speed), ``omega_max * l``."""
    sv, g = scene.servo, scene.gait
    omega = sv.max_speed_rad_s if sv.max_speed_rad_s > 0 else 2.0 * g.amplitude_rad * g.angular_frequency_rad_s
    return omega * scene.geometry.link_length_m


def snap_timestep(raw_s: float) -> float:
    """The largest ``2 ms / k`` (integer ``k``) not above ``raw_s``, s."""
    k = max(1, math.ceil(MAX_AUTO_TIMESTEP_S / raw_s - 1e-9))
    return MAX_AUTO_TIMESTEP_S / k


def auto_timestep(scene: Scene) -> float:
    """The integrator step the scene needs, s: the time-step rule.

    ``dt = 2 ms / k`` with the smallest integer ``k`` that meets the
    criteria:

    * **servo**: ``omega_servo dt <= 0.5`` (:func:`servo_frequency_rad_s`).
      The servo stiffness is integrated explicitly (implicitfast treats only
      damping implicitly); the servo's period then spans >= 12 steps.
    * **gait**: ``2 pi f dt <= 0.5``, the same bound for the commanded wave:
      a gait period spans >= 12 steps (binding only above ~40 Hz; a faster
      gait was aliased by the 2 ms step, and at 1e12 Hz diverged).
    * **contact** (only where bodies can touch, :func:`contact_possible`):
      ``v_max dt <= target_penetration_m`` (1 mm), with ``v_max`` from
      :func:`approach_speed_m_s`: no point of a body moves further than the
      penetration bound in one step.  Contacts are detected only at the
      steps, so a body arriving at ``v`` is up to ``v dt`` deep when its
      contact first exists; the soft contact (time constant ``2 dt``) then
      stops it within a few steps.  Measured in jammed packs: the deepest
      contacts arrive at ~1.1 m/s and reach ~1.2 ``v dt``.

    ``2 ms / k`` keeps every recording interval that is a multiple of 2 ms an
    exact number of steps.  Results at the defaults: 2 ms for a lone 3-link
    swimmer away from walls; 0.67 ms for 3-link scenes with contact (pairs,
    groups, packs: 1.08 m/s top speed); 0.5 ms for 2 links; 1 ms for 4;
    servo-limited from 5 links on (0.67 ms for 5, 0.5 ms for 7, 0.4 ms for 9,
    0.25 ms for 12).  Convergence and penetration:
    docs/timestep.md and docs/contact.md.
    """
    raw = SERVO_STEP_FRACTION / max(servo_frequency_rad_s(scene), scene.gait.angular_frequency_rad_s)
    if contact_possible(scene):
        raw = min(raw, scene.contact.target_penetration_m / approach_speed_m_s(scene))
    return snap_timestep(raw)


@dataclass(frozen=True)
class SceneIndex:
    """Addresses in the compiled model, resolved once by name.

    All arrays have a leading swimmer axis.  ``qpos_root[j] = (x, y, yaw)``
    addresses (x is -1 for a scene with ``hold_x``: no x joint), ``qvel_joint[j, i]``
    the hinge speed of joint ``i``, ``sens_load[j, i]`` the servo torque sensor of
    joint ``i`` (closed-loop controllers only; shape ``(n, 0)`` otherwise), ``qpos_joint[j, i]`` the hinge of joint ``i``;
    ``ctrl_pos[j, i]`` / ``ctrl_vel[j, i]`` the servo's position / velocity
    set-point inputs; ``ctrl_push[j, k]`` the perturbation force input on link ``k`` (N;
    shape ``(n, 0)`` when the scene has no ``forces_N``); ``ctrl_heading[j]`` the heading guide's
    (yaw set-point, rate) inputs (shape ``(n, 0)`` without :attr:`~undulate.params.Scene.heading_guide`);
    ``sens_com[j]`` the first of 3 sensordata entries of the centre of mass;
    ``sens_pair[p]`` the 3-vector net force between swimmers ``p, p+1``;
    ``sens_wall[k]`` the 3-vector net force of all swimmers on wall ``k``
    (lower, upper, then end walls if any); ``sens_mindist`` the (found, dist) pair
    of the deepest contact.
    """

    qpos_root: np.ndarray
    qpos_joint: np.ndarray
    qvel_root: np.ndarray
    qvel_joint: np.ndarray
    sens_load: np.ndarray
    ctrl_pos: np.ndarray
    ctrl_vel: np.ndarray
    ctrl_push: np.ndarray
    sens_com: np.ndarray
    ctrl_heading: np.ndarray
    sens_pair: np.ndarray
    sens_wall: np.ndarray
    sens_mindist: int
    wall_names: tuple[str, ...]


@dataclass(frozen=True)
class CompiledScene:
    """A compiled model, its index and the scene it was built from."""

    model: mujoco.MjModel
    index: SceneIndex
    scene: Scene

    def controls(self, t_s: np.ndarray) -> np.ndarray:
        """Open-loop control vectors at times ``t_s`` (shape ``T``) -> ``T x nu``.

        Servo inputs are the gait's angle and angular-velocity set-points (rad,
        rad/s; the angle set-point leads by ``b omega_cmd / kp``, the back-EMF
        feed-forward of :attr:`~undulate.params.Servo.back_emf`); push inputs are the perturbation forces (N), on from
        ``scene.force_onset_s``; heading-guide inputs are :func:`chord_heading` of the commanded
        angles (rad, rad/s).
        """
        sc, ix = self.scene, self.index
        n_links = sc.geometry.n_links
        u = np.zeros((len(t_s), self.model.nu))
        omega_cmd = sc.gait.joint_velocities(t_s, sc.phases_rad, n_links)
        # back-EMF feed-forward b omega_cmd, expressed as a position set-point offset b omega_cmd / kp
        lead = sc.servo.back_emf_Nms_per_rad / sc.servo.kp_Nm_per_rad
        u[:, ix.ctrl_pos] = sc.gait.joint_angles(t_s, sc.phases_rad, n_links) + lead * omega_cmd
        u[:, ix.ctrl_vel] = omega_cmd
        if sc.forces_N is not None:
            on = (np.asarray(t_s) >= sc.force_onset_s)[:, None]
            if sc.force_offset_s is not None:
                on &= (np.asarray(t_s) < sc.force_offset_s)[:, None]
            per_link = np.asarray(sc.forces_N)[:, None] / sc.geometry.n_links * np.ones(ix.ctrl_push.shape)
            u[:, ix.ctrl_push] = np.where(on[..., None], per_link[None], 0.0)
        if ix.ctrl_heading.size:  # the commanded shape's chord along x (not the lead-corrected set-point)
            ang = sc.gait.joint_angles(t_s, sc.phases_rad, n_links)
            yaw, rate = chord_heading(ang, omega_cmd, n_links)
            u[:, ix.ctrl_heading[:, 0]], u[:, ix.ctrl_heading[:, 1]] = yaw, rate
        return u


def scene_spec(scene: Scene, timestep_s: float, *, pair_sensors: bool = True, push: bool | None = None,
               loads: bool | None = None, servo: str = "pid") -> tuple[mujoco.MjSpec, tuple[str, ...]]:
    """The full scene: channel walls plus ``scene.n_swimmers`` attached swimmers.

    ``pair_sensors=False`` leaves out the swimmer-swimmer contact-force
    sensors (each scans every contact every step: in a jammed 50-swimmer
    pack they cost more than the collision detection).
    Returns the spec and the wall geom names (lower, upper[, end_lo, end_hi]).
    """
    g = scene.geometry
    ch = scene.channel
    spec = mujoco.MjSpec()
    spec.modelname = "undulate"
    opt = spec.option
    opt.timestep = timestep_s
    opt.gravity = [0, 0, 0]
    opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    opt.cone = mujoco.mjtCone.mjCONE_PYRAMIDAL
    opt.solver = mujoco.mjtSolver.mjSOL_NEWTON
    opt.viscosity = 0.0 if scene.ground.mode == "resistive" else drag_viscosity(scene)  # resistive: the
    # drag actuators are the whole medium
    opt.density = scene.ground.fluid_density_kg_m3 if scene.ground.mode == "swimming" else 0.0
    opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS)
    opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_DIAGEXACT)  # exact constraint regularisation

    half_d = ch.width_m / 2
    wall_common = dict(
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        **_contact_attrs(scene, timestep_s),
        contype=2,
        conaffinity=1,
        rgba=list(_WALL_RGBA),
    )
    wb = spec.worldbody
    walls = ["wall_lo", "wall_hi"]
    wb.add_geom(name="wall_lo", pos=[0, -half_d, 0], quat=list(_Q_ALONG_Y_UP),
                size=[ch.length_m / 2, g.height_m, 0.05], **wall_common)
    wb.add_geom(name="wall_hi", pos=[0, half_d, 0], quat=list(_Q_ALONG_Y_DOWN),
                size=[ch.length_m / 2, g.height_m, 0.05], **wall_common)
    if ch.end_walls_m is not None:
        half_e = ch.end_walls_m / 2
        wb.add_geom(name="wall_end_lo", pos=[-half_e, 0, 0], quat=list(_Q_ALONG_X_UP),
                    size=[half_d, g.height_m, 0.05], **wall_common)
        wb.add_geom(name="wall_end_hi", pos=[half_e, 0, 0], quat=list(_Q_ALONG_X_DOWN),
                    size=[half_d, g.height_m, 0.05], **wall_common)
        walls += ["wall_end_lo", "wall_end_hi"]

    xs, ys = scene.initial_x_m(), scene.initial_y_m()
    one = swimmer_spec(scene, timestep_s, push=push, servo=servo)
    spec.copy_during_attach = True  # attach the same swimmer N times
    L = g.length_m
    for j in range(scene.n_swimmers):
        frame = wb.add_frame(pos=[xs[j] - L / 2 + root_offset_m(scene), ys[j], 0])
        spec.attach(one, prefix=f"s{j}_", frame=frame)

    # sensors: names resolved to addresses after compilation
    rl = root_link(g.n_links)
    for j in range(scene.n_swimmers):
        spec.add_sensor(name=f"s{j}_com", type=mujoco.mjtSensor.mjSENS_SUBTREECOM,
                        objtype=mujoco.mjtObj.mjOBJ_BODY, objname=f"s{j}_link{rl}")
    _FORCE, _NET = 2, 3  # contact sensor: data="force", reduce="netforce"
    for j in range(scene.n_swimmers - 1 if pair_sensors else 0):
        s = spec.add_sensor(name=f"pair{j}_force", type=mujoco.mjtSensor.mjSENS_CONTACT,
                            objtype=mujoco.mjtObj.mjOBJ_XBODY, objname=f"s{j}_link{rl}",
                            reftype=mujoco.mjtObj.mjOBJ_XBODY, refname=f"s{j + 1}_link{rl}")
        s.intprm[:3] = [_FORCE, _NET, 1]
    for wname in walls:
        s = spec.add_sensor(name=f"{wname}_force", type=mujoco.mjtSensor.mjSENS_CONTACT,
                            objtype=mujoco.mjtObj.mjOBJ_GEOM, objname=wname)
        s.intprm[:3] = [_FORCE, _NET, 1]
    _FOUND_DIST, _MINDIST = 1 | 8, 1  # data="found dist", reduce="mindist"
    s = spec.add_sensor(name="mindist", type=mujoco.mjtSensor.mjSENS_CONTACT)
    s.intprm[:3] = [_FOUND_DIST, _MINDIST, 1]
    if scene.controller.closed_loop if loads is None else loads:  # each servo's "present load": what a
        # closed-loop controller senses
        for j in range(scene.n_swimmers):
            for i in range(g.n_links - 1):
                spec.add_sensor(name=f"s{j}_load{i}", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                                objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=f"s{j}_servo{i}")
    return spec, tuple(walls)


def build(scene: Scene, timestep_s: float | None = None, *, pair_sensors: bool = True,
          push: bool | None = None, loads: bool | None = None, servo: str = "pid") -> CompiledScene:
    """Compile ``scene`` (time step: ``timestep_s``, or :func:`auto_timestep`)
    and resolve every address by name.  ``pair_sensors``: see :func:`scene_spec`
    (without them ``index.sens_pair`` is empty).  ``servo``: :data:`SERVO_MODELS` (with
    ``"affine"``, ``index.ctrl_vel`` repeats ``ctrl_pos``: the servo has one input)."""
    if not isinstance(scene, Scene):
        raise ParameterError("scene", "a Scene", type(scene).__name__)
    if timestep_s is None:
        timestep_s = auto_timestep(scene)
    push = scene.forces_N is not None if push is None else push
    loads = scene.controller.closed_loop if loads is None else loads
    spec, walls = scene_spec(scene, timestep_s, pair_sensors=pair_sensors, push=push, loads=loads, servo=servo)
    model = spec.compile()
    n, nj = scene.n_swimmers, scene.geometry.n_links - 1

    def jadr(name: str) -> int:
        return int(model.jnt_qposadr[model.joint(name).id])

    def vadr(name: str) -> int:
        return int(model.jnt_dofadr[model.joint(name).id])

    def cadr(name: str) -> int:
        return int(model.actuator_ctrladr[model.actuator(name).id])

    def sadr(name: str) -> int:
        return int(model.sensor_adr[model.sensor(name).id])

    index = SceneIndex(
        qpos_root=np.array([[jadr(f"s{j}_{q}") if not (q == "x" and scene.hold_x) else -1
                             for q in ("x", "y", "yaw")] for j in range(n)], dtype=int),
        qpos_joint=np.array([[jadr(f"s{j}_j{i}") for i in range(nj)] for j in range(n)], dtype=int).reshape(n, nj),
        qvel_root=np.array([[vadr(f"s{j}_{q}") if not (q == "x" and scene.hold_x) else -1
                             for q in ("x", "y", "yaw")] for j in range(n)], dtype=int),
        qvel_joint=np.array([[vadr(f"s{j}_j{i}") for i in range(nj)] for j in range(n)], dtype=int).reshape(n, nj),
        sens_load=np.array([[sadr(f"s{j}_load{i}") for i in range(nj)] for j in range(n)]
                           if loads else np.zeros((n, 0)), dtype=int).reshape(n, -1),
        ctrl_pos=np.array([[cadr(f"s{j}_servo{i}") for i in range(nj)] for j in range(n)], dtype=int).reshape(n, nj),
        ctrl_vel=np.array([[cadr(f"s{j}_servo{i}") + (servo == "pid") for i in range(nj)] for j in range(n)], dtype=int).reshape(n, nj),
        ctrl_push=np.array([[cadr(f"s{j}_push{k}") for k in range(nj + 1)] for j in range(n)] if push
                           else np.zeros((n, 0)), dtype=int),
        sens_com=np.array([sadr(f"s{j}_com") for j in range(n)], dtype=int),
        ctrl_heading=np.array([[cadr(f"s{j}_headguide"), cadr(f"s{j}_headguide") + (servo == "pid")] for j in range(n)]
                              if scene.heading_guide else np.zeros((n, 0)), dtype=int),
        sens_pair=np.array([sadr(f"pair{j}_force") for j in range(n - 1 if pair_sensors else 0)], dtype=int),
        sens_wall=np.array([sadr(f"{w}_force") for w in walls], dtype=int),
        sens_mindist=sadr("mindist"),
        wall_names=walls,
    )
    return CompiledScene(model=model, index=index, scene=scene)
