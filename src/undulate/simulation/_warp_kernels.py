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


@wp.kernel
def reduce(qpos: wp.array2d(dtype=float), qvel: wp.array2d(dtype=float), sens: wp.array2d(dtype=float),
           k: wp.array(dtype=int), sps: int, pair_adr: wp.array(dtype=int), wall_adr: wp.array(dtype=int),
           md: int, maxpen: wp.array(dtype=float), out_q: wp.array3d(dtype=float), out_v: wp.array3d(dtype=float),
           out_s: wp.array3d(dtype=float), pn: wp.array2d(dtype=float), fp: wp.array3d(dtype=float),
           fw: wp.array3d(dtype=float), bad: wp.array(dtype=int)):
    """What the recorder keeps of step k, reduced on the device (undulate.simulation's ``_Stepper``
    does the same on the host from every step): the state and sensors at the last step of each sample
    interval of ``sps`` steps, the interval's deepest penetration and its mean pair and wall force
    magnitudes, and the first step at which a world blew up (``bad``: 4 (step + 1) + 1 for a huge or
    non-finite state, + 2 for interpenetration beyond ``maxpen``; 0 while none)."""
    w = wp.tid()
    i = k[0]
    j = i // sps
    first = i % sps == 0
    depth = float(0.0)  # a dynamic variable (assigned in a branch)
    if sens[w, md] > 0.0:
        depth = wp.max(0.0, -sens[w, md + 1])
    if first:
        pn[j, w] = depth
    else:
        pn[j, w] = wp.max(pn[j, w], depth)
    inv = 1.0 / float(sps)
    for p in range(pair_adr.shape[0]):
        a = pair_adr[p]
        f = wp.sqrt(sens[w, a] * sens[w, a] + sens[w, a + 1] * sens[w, a + 1] + sens[w, a + 2] * sens[w, a + 2]) * inv
        if first:
            fp[j, w, p] = f
        else:
            fp[j, w, p] = fp[j, w, p] + f
    for p in range(wall_adr.shape[0]):
        a = wall_adr[p]
        f = wp.sqrt(sens[w, a] * sens[w, a] + sens[w, a + 1] * sens[w, a + 1] + sens[w, a + 2] * sens[w, a + 2]) * inv
        if first:
            fw[j, w, p] = f
        else:
            fw[j, w, p] = fw[j, w, p] + f
    if bad[w] == 0:
        huge = int(0)
        for c in range(qpos.shape[1]):
            if not (wp.abs(qpos[w, c]) < 1.0e6):
                huge = 1
        for c in range(qvel.shape[1]):
            if not (wp.abs(qvel[w, c]) < 1.0e6):
                huge = 1
        if huge == 1:
            bad[w] = 4 * (i + 1) + 1
        elif depth > maxpen[w]:
            bad[w] = 4 * (i + 1) + 2
    if i % sps == sps - 1:
        for c in range(qpos.shape[1]):
            out_q[j, w, c] = qpos[w, c]
        for c in range(qvel.shape[1]):
            out_v[j, w, c] = qvel[w, c]
        for c in range(sens.shape[1]):
            out_s[j, w, c] = sens[w, c]
