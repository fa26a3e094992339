"""Warp kernels of the MuJoCo Warp backend (:mod:`undulate._warp`); imported only with the ``gpu`` extra.

No ``from __future__ import annotations`` here: Warp reads the kernels' annotations as types."""

import warp as wp


@wp.kernel
def set_ctrl(table: wp.array3d(dtype=float), k: wp.array(dtype=int), ctrl: wp.array2d(dtype=float)):
    """ctrl[w, :] = the control table's row of step k (table: step, world, input)."""
    w, j = wp.tid()
    ctrl[w, j] = table[k[0], w, j]


@wp.kernel
def record(qpos: wp.array2d(dtype=float), qvel: wp.array2d(dtype=float), sens: wp.array2d(dtype=float),
           k: wp.array(dtype=int), out_q: wp.array3d(dtype=float), out_v: wp.array3d(dtype=float),
           out_s: wp.array3d(dtype=float)):
    """The state and sensors of every world after step k, into row k of the chunk's buffers."""
    w = wp.tid()
    i = k[0]
    for j in range(qpos.shape[1]):
        out_q[i, w, j] = qpos[w, j]
    for j in range(qvel.shape[1]):
        out_v[i, w, j] = qvel[w, j]
    for j in range(sens.shape[1]):
        out_s[i, w, j] = sens[w, j]


@wp.kernel
def incr(k: wp.array(dtype=int)):
    """The device-side step counter of a chunk (so one captured graph serves every step)."""
    k[0] = k[0] + 1
