"""The CPU model's ``pid`` servos as the Warp model's affine servos: the Warp model derived from the
host's compiled model (:func:`device_model`: each scene is compiled once), and the set-point slew
limit that MuJoCo's ``pid`` applies inside the step (``Servo.max_speed_rad_s``) applied to the
control stream, step by step, with the same rule (:class:`AffineServoTable`, :func:`slew`)."""

from __future__ import annotations

import copy
from collections.abc import Sequence

import mujoco
import numpy as np

from ..errors import ParameterError, UndulateError

__all__ = ["AffineServoTable", "device_model", "device_inputs", "slew"]


def _pid_servos(cpu: mujoco.MjModel) -> np.ndarray:
    """The ``pid`` actuators of ``cpu`` (ids), refused where one has an integral term (MuJoCo Warp has
    no ``pid`` actuator, and an affine servo has no integral state)."""
    pid = np.flatnonzero(cpu.actuator_gaintype == mujoco.mjtGain.mjGAIN_PID)
    for i in pid:
        if cpu.actuator_actnum[i] > 1 or float(cpu.actuator_dynprm[i, 0]) > 0:
            raise ParameterError("servo", "without an integral term (ki <= 0) on the 'warp' backend "
                                 "(MuJoCo Warp has no pid actuator)",
                                 mujoco.mj_id2name(cpu, mujoco.mjtObj.mjOBJ_ACTUATOR, int(i)))
    return pid


def device_model(cpu: mujoco.MjModel) -> mujoco.MjModel:
    """The Warp model of a scene, from its host model as compiled (``servo="pid"``), without compiling
    the scene again: a copy whose ``pid`` servos are the affine position servos
    (:data:`undulate.scene.SERVO_MODELS`, force ``kp u - kp q - kv qdot``).

    A ``pid`` servo without an integral term carries its gains as the affine servo does
    (``biasprm = (0, -kp, -kv)``) and differs in its gain (``kp``, from ``biasprm[1]``, fixed), its
    dynamics (none: the slew limit is applied on the host, :class:`AffineServoTable`) and its inputs
    (its first, the position set-point, alone).  Every field MuJoCo Warp reads is then the one the
    compiled ``"affine"`` scene has, but for the sizes fixed by compilation: the model keeps the
    host's control layout (``nu``: the servos' velocity inputs stay, never read and left at zero;
    :func:`device_inputs` names those the device fills) and its ``na`` slew states, which no
    actuator reads (tests/test_warp.py compares the two models field by field)."""
    if cpu.ntendon:  # MuJoCo Warp's tendon actuation launches over nu as if nu were the actuators: the
        # kept velocity inputs would make it read past them (our scenes have no tendons)
        raise UndulateError(f"the Warp model of a scene with tendons ({cpu.ntendon}) cannot keep the host's "
                            "control layout; compile it with servo='affine'")
    pid = _pid_servos(cpu)
    m = copy.copy(cpu)  # mj_copyModel: the host's model is left as it is
    if pid.size:
        kp = -m.actuator_biasprm[pid, 1]
        m.actuator_gaintype[pid] = mujoco.mjtGain.mjGAIN_FIXED
        m.actuator_gainprm[pid] = 0.0
        m.actuator_gainprm[pid, 0] = kp
        m.actuator_dyntype[pid] = mujoco.mjtDyn.mjDYN_NONE
        m.actuator_dynprm[pid] = 0.0
        m.actuator_dynprm[pid, 0] = 1.0  # MuJoCo's default time constant (read only by filter dynamics)
        m.actuator_actadr[pid] = -1
        m.actuator_actnum[pid] = 0
        m.actuator_ctrlnum[pid] = 1
        m.actuator_ctrlspec[pid] = int(mujoco.mjtCtrlInput.mjINPUT_POS)
    return m


def device_inputs(m: mujoco.MjModel) -> np.ndarray:
    """The control inputs of ``m`` its actuators read (ctrl indices, in actuator order): the columns of
    the Warp model's control table (all of them for a compiled ``"affine"`` scene; for a
    :func:`device_model`, each servo's position input and every other actuator's inputs)."""
    parts = [m.actuator_ctrladr[i] + np.arange(m.actuator_ctrlnum[i]) for i in range(m.nactuator)]
    return np.concatenate(parts).astype(int) if parts else np.zeros(0, int)


class AffineServoTable:
    """The CPU model's ``pid`` servos expressed as the Warp model's affine servos, and the set-point
    slew limit applied to the control stream (:mod:`undulate.simulation._warp`'s docstring): the
    Warp model's control table of a chunk (:meth:`table`)."""

    def __init__(self, cpu: mujoco.MjModel, aff: mujoco.MjModel, dt: float, models: Sequence[mujoco.MjModel]):
        """``cpu``: the first scene's model (the layout); ``aff``: its Warp model (:func:`device_model`, or
        the scene compiled with ``servo="affine"``), whose table columns are :func:`device_inputs`;
        ``models``: every scene's (gains and slew rates may differ per scene: ``ratio`` and ``rate``
        have one row per scene)."""
        pid = _pid_servos(cpu).tolist()
        other = [i for i in range(cpu.nactuator) if i not in pid and cpu.actuator_ctrlnum[i] > 0]
        column = {int(c): j for j, c in enumerate(device_inputs(aff))}

        def dst(i: int) -> int:  # the table column of CPU actuator i's input in the Warp model (same name)
            return column[int(aff.actuator_ctrladr[aff.actuator(cpu.actuator(i).name).id])]

        adr = cpu.actuator_ctrladr
        self.src_pos = np.array([adr[i] for i in pid], int)
        self.src_vel = self.src_pos + 1
        self.dst = np.array([dst(i) for i in pid], int)
        self.act = np.array([cpu.actuator_actadr[i] if cpu.actuator_actnum[i] == 1 else -1 for i in pid], int)
        self.copy_src, self.copy_dst = np.array([adr[i] for i in other], int), np.array([dst(i) for i in other], int)
        self.nu = len(column)
        pid = np.array(pid, int)
        self.ratio = np.stack([m.actuator_biasprm[pid, 2] / m.actuator_biasprm[pid, 1] for m in models])  # kv / kp
        self.rate = np.stack([np.where((m.actuator_dynprm[pid, 1] > 0) & (m.actuator_actnum[pid] == 1),
                                       m.actuator_dynprm[pid, 1] * dt, np.inf) for m in models])  # slewmax dt

    def table(self, u: np.ndarray, act0: np.ndarray):
        """Controls ``u`` (nb, k, nu of the CPU model) -> the Warp model's (k, nb, nu) float32 table,
        and the slew states after every step (nb, k, nservo; a view of a step-major array).  ``act0``:
        the slew states at the start (nb, nservo; NaN where a servo has none).  Built step-major, as
        the table is, so each step's rows are contiguous, with slices where the columns are evenly
        spaced (the host's share of a chunk: docs/gpu.md, "The host's share")."""
        nb, k = u.shape[:2]
        ut = u.transpose(1, 0, 2)
        out = np.zeros((k, nb, self.nu), np.float32)
        if self.copy_dst.size:
            out[:, :, _cols(self.copy_dst)] = ut[:, :, _cols(self.copy_src)]
        slewed = _slew_steps(np.ascontiguousarray(ut[:, :, _cols(self.src_pos)]), self.rate, act0)
        out[:, :, _cols(self.dst)] = slewed + self.ratio[None] * ut[:, :, _cols(self.src_vel)]
        return out, slewed.transpose(1, 0, 2)


def _idle_controls(u: np.ndarray, active: np.ndarray | None, nstep: int) -> np.ndarray:
    """The first ``nstep`` steps' controls of ``u`` (nb, k, nu), zero for the scenes outside ``active``
    (set in place).  A scene its rule stopped still steps on the device, its steps thrown away, under
    rows nothing fills once it stopped (and unset in a new buffer): garbage there (inf once cast to
    float32, NaN) could overflow its world's contact capacity, a CapacityError for the whole batch, or
    keep the solver iterating on a GPU."""
    if active is not None and not active.all():
        u[~active, :nstep] = 0.0
    return u[:, :nstep]


def _cols(idx: np.ndarray):
    """``idx`` as a slice where its columns are evenly spaced and ascending (a view, not a gather)."""
    step = int(idx[1] - idx[0]) if idx.size > 1 else 1
    if idx.size and step > 0 and (np.diff(idx) == step).all():
        return slice(int(idx[0]), int(idx[-1]) + 1, step)
    return idx


def slew(target: np.ndarray, rate: np.ndarray, act0: np.ndarray) -> np.ndarray:
    """The slew states after every step: MuJoCo's rule, the state moves toward the command by at
    most ``slewmax dt`` a step, ``s <- s + clip(target - s, -rate, rate)``, from ``act0``.

    ``target``: (nb, k, nservo) commands; ``rate``: (nb, nservo) ``slewmax dt`` (inf: no slew limit,
    the state is the command); ``act0``: (nb, nservo).  Bitwise the step-by-step rule, without a
    Python step per step where it can be skipped: once every state equals its command, the rule
    gives the command itself at each following step whose change is within the rate and exact in
    floating point (``t + (t' - t) == t'``), so those steps are copied whole (a gait within the
    servos' speed is all such steps after the start's ramp)."""
    return _slew_steps(np.ascontiguousarray(target.transpose(1, 0, 2)), rate, act0).transpose(1, 0, 2)


def _slew_steps(target: np.ndarray, rate: np.ndarray, act0: np.ndarray) -> np.ndarray:
    """:func:`slew` on step-major commands (k, nb, nservo) -> step-major states: every step's rows
    contiguous, as the control table is."""
    k = target.shape[0]
    finite = np.isfinite(rate)
    out = np.empty_like(target)
    if not finite.any() or k == 0:
        out[:] = target
        return out
    r = np.where(finite, rate, 0.0)
    d = target[1:] - target[:-1]
    exact = ((np.abs(d) <= r[None]) & (target[:-1] + d == target[1:])) | ~finite[None]
    breaks = np.flatnonzero(~exact.all(axis=(1, 2)))  # step j -> j + 1 not followed exactly
    s = np.where(finite, act0, 0.0)
    i = 0
    while i < k:
        s = np.where(finite, s + np.clip(target[i] - s, -r, r), target[i])
        out[i] = s
        if np.array_equal(s, target[i]):  # on its command: copy the steps that follow exactly
            nxt = np.searchsorted(breaks, i)
            end = int(breaks[nxt]) if nxt < len(breaks) else k - 1  # the last step reached exactly
            out[i + 1:end + 1] = target[i + 1:end + 1]
            s = target[end].copy()
            i = end
        i += 1
    return out
