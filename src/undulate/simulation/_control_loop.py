"""Closed-loop chunks: a controller that senses between control periods drives the servos (one
rollout a control period), or one whose commands do not depend on what it senses (one rollout a
chunk, its senses handed over after)."""

from __future__ import annotations

import numpy as np

from ..control import Controller
from ._compile import controls
from ._engines import Rollout

def _push_controls(ctrl_buf: np.ndarray, compiled, t: np.ndarray) -> None:
    """Zero a closed-loop chunk's controls, then the perturbation forces from each scene's own controls."""
    ctrl_buf[:] = 0.0
    if compiled[0].index.ctrl_push.size:
        for b, cs in enumerate(compiled):
            ctrl_buf[b] = controls(cs, t)


def _set_points(u: np.ndarray, ang: np.ndarray, vel: np.ndarray, lead: float, pos_cols, vel_cols) -> None:
    """Servo set-points into controls ``u`` (nb, T, nu) from commands (T, nb, ...): the angle plus the
    back-EMF lead ``b omega / kp``, and the velocity."""
    n_t, nb = ang.shape[:2]
    u[:, :, pos_cols] = (ang + lead * vel).reshape(n_t, nb, -1).transpose(1, 0, 2)
    u[:, :, vel_cols] = vel.reshape(n_t, nb, -1).transpose(1, 0, 2)


def _closed_loop_chunk(ctl: Controller, compiled, runner: Rollout, cur, last_sens, t, tick, rows, t_rows,
                       state_buf, sens_buf, ctrl_buf, q0, clock, active=None):
    """Step one chunk a control period at a time: sense, command, roll out in C.

    ``cur`` (the state at the chunk's start) is updated in place.  Returns the
    chunk's states, sensor data, and the commanded joint angles and gait phases
    at the recorded ``rows`` (each ``(len(rows), nb, n, nj)`` / ``(len(rows), nb, n)``).
    ``active``: a mask of the scenes to step (None: all); the others stay where they are.
    """
    nb, k = state_buf.shape[:2]
    cs0 = compiled[0]
    ix, m0 = cs0.index, cs0.model
    sc = cs0.scene
    qv0 = q0 + m0.nq
    lead = sc.servo.back_emf_Nms_per_rad / sc.servo.kp_Nm_per_rad
    qpos_j, qvel_j, load_j = ix.qpos_joint, ix.qvel_joint, ix.sens_load
    pos_cols, vel_cols = ix.ctrl_pos, ix.ctrl_vel
    n_rows = len(rows)
    cmd_rows = np.empty((n_rows, nb) + qpos_j.shape)
    phase_rows = np.empty((n_rows, nb, qpos_j.shape[0]))
    _push_controls(ctrl_buf, compiled, t)
    pos_flat, vel_flat = pos_cols.ravel(), vel_cols.ravel()
    # the sensed joints: views of the current state and of the last step's sensors
    sens = last_sens
    one = nb == 1  # one scene: the chunk buffers' slices are contiguous, roll out straight into them
    if not one:
        u_t = np.empty((nb, tick, m0.nu))
        st_t = np.empty((nb, tick, state_buf.shape[2]))
        sd_t = np.empty((nb, tick, sens_buf.shape[2]))
    a = 0
    while a < k:
        e = min(k, a + tick)
        n_t = e - a
        ang, vel = ctl.commands(t[a:e], cur[:, q0 + qpos_j], cur[:, qv0 + qvel_j], sens[:, load_j])
        # set-points for these steps: angle (+ the back-EMF lead b omega / kp) and velocity
        if one:
            u, st, sd = ctrl_buf[:, a:e], state_buf[:, a:e], sens_buf[:, a:e]
        else:
            u = ctrl_buf[:, a:e].copy() if n_t != tick else u_t
            if n_t == tick:
                u[:] = ctrl_buf[:, a:e]
            st = st_t if n_t == tick else np.empty((nb, n_t, state_buf.shape[2]))
            sd = sd_t if n_t == tick else np.empty((nb, n_t, sens_buf.shape[2]))
        _set_points(u, ang, vel, lead, pos_flat, vel_flat)
        # what is recorded at the samples inside this period (states after step r, at time t[r] + dt)
        sel = (rows >= a) & (rows < e)
        if sel.any():
            tr = t_rows[sel]
            cmd_rows[sel] = ctl.commands(tr)[0]
            phase_rows[sel] = ctl.gait_phase(tr)
        clock.rollout(runner, nb, n_t, cur, u, st, sd, n_t, active=active)
        if not one:
            ctrl_buf[:, a:e], state_buf[:, a:e], sens_buf[:, a:e] = u, st, sd
        cur[:] = st[:, -1]
        sens = sd[:, -1]
        a = e
    return state_buf, sens_buf, cmd_rows, phase_rows


def _feed_forward_chunk(ctl: Controller, compiled, runner: Rollout, cur, last_sens, t, tick, rows, t_rows,
                        state_buf, sens_buf, ctrl_buf, q0, clock, active=None):
    """:func:`_closed_loop_chunk` for a controller whose commands do not depend on what it senses
    (``Controller.feed_forward``): the whole chunk in one rollout, then what was sensed at each
    control update (the state after the step before it, that step's sensors) handed to
    ``ctl.sense``.  Bitwise the states, sensor data and senses of stepping period by period."""
    nb, k = state_buf.shape[:2]
    ix, m0, sv = compiled[0].index, compiled[0].model, compiled[0].scene.servo
    qpos_j, qvel_j, load_j = q0 + ix.qpos_joint, q0 + m0.nq + ix.qvel_joint, ix.sens_load
    _push_controls(ctrl_buf, compiled, t)
    ang, vel = ctl.commands(t)
    _set_points(ctrl_buf, ang, vel, sv.back_emf_Nms_per_rad / sv.kp_Nm_per_rad, ix.ctrl_pos.ravel(),
                ix.ctrl_vel.ravel())
    clock.rollout(runner, nb, k, cur, ctrl_buf, state_buf, sens_buf, k, active=active)
    for a in range(0, k, tick):
        st, sd = (cur, last_sens) if a == 0 else (state_buf[:, a - 1], sens_buf[:, a - 1])
        ctl.sense(float(t[a]), st[:, qpos_j], st[:, qvel_j], sd[:, load_j])
    cur[:] = state_buf[:, -1]
    return state_buf, sens_buf, ctl.commands(t_rows)[0], ctl.gait_phase(t_rows)
