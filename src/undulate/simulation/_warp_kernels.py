"""Warp kernels of the MuJoCo Warp backend (:mod:`undulate._warp`); imported only with the ``gpu`` extra.

No ``from __future__ import annotations`` here: Warp reads the kernels' annotations as types."""

import warp as wp


@wp.kernel
def set_ctrl(table: wp.array3d(dtype=float), k: wp.array(dtype=int), cols: wp.array(dtype=int),
             ctrl: wp.array2d(dtype=float)):
    """ctrl[w, cols] = the control table's row of step k (table: step, world, input j of the model's
    inputs ``cols``, the ones its actuators read; the others stay as they are)."""
    w, j = wp.tid()
    ctrl[w, cols[j]] = table[k[0], w, j]


@wp.func
def _copy_row(src: wp.array2d(dtype=float), w: int, dst: wp.array3d(dtype=float), i: int):
    """dst[i, w, :] = src[w, :]."""
    for c in range(src.shape[1]):
        dst[i, w, c] = src[w, c]


@wp.kernel
def record(qpos: wp.array2d(dtype=float), qvel: wp.array2d(dtype=float), sens: wp.array2d(dtype=float),
           k: wp.array(dtype=int), out_q: wp.array3d(dtype=float), out_v: wp.array3d(dtype=float),
           out_s: wp.array3d(dtype=float)):
    """The state and sensors of every world after step k, into row k of the chunk's buffers."""
    w = wp.tid()
    i = k[0]
    _copy_row(qpos, w, out_q, i)
    _copy_row(qvel, w, out_v, i)
    _copy_row(sens, w, out_s, i)


@wp.kernel
def incr(k: wp.array(dtype=int)):
    """The device-side step counter of a chunk (so one captured graph serves every step)."""
    k[0] = k[0] + 1


@wp.func
def _add_force_means(sens: wp.array2d(dtype=float), w: int, adr: wp.array(dtype=int), out: wp.array3d(dtype=float),
                     j: int, first: bool, inv: float):
    """out[j, w, p] (+)= |force sensor p| / sps: the magnitude of each 3-vector sensor at ``adr``,
    accumulated into its sample interval's mean (set at the interval's first step)."""
    for p in range(adr.shape[0]):
        a = adr[p]
        f = wp.sqrt(sens[w, a] * sens[w, a] + sens[w, a + 1] * sens[w, a + 1] + sens[w, a + 2] * sens[w, a + 2]) * inv
        if first:
            out[j, w, p] = f
        else:
            out[j, w, p] = out[j, w, p] + f


@wp.func
def _huge(x: wp.array2d(dtype=float), w: int) -> int:
    """1 if a component of row w is non-finite or beyond 1e6 (the host's divergence bound), else 0."""
    huge = int(0)
    for c in range(x.shape[1]):
        if not (wp.abs(x[w, c]) < 1.0e6):
            huge = 1
    return huge


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
    _add_force_means(sens, w, pair_adr, fp, j, first, inv)
    _add_force_means(sens, w, wall_adr, fw, j, first, inv)
    if bad[w] == 0:
        if _huge(qpos, w) + _huge(qvel, w) > 0:
            bad[w] = 4 * (i + 1) + 1
        elif depth > maxpen[w]:
            bad[w] = 4 * (i + 1) + 2
    if i % sps == sps - 1:
        _copy_row(qpos, w, out_q, j)
        _copy_row(qvel, w, out_v, j)
        _copy_row(sens, w, out_s, j)
