"""Which scenes of a batch share one Warp model: worlds that differ only in fields MuJoCo Warp
batches per world (channel width, drag, gains, contact stiffness, ...) are one model with those fields
given per world (:func:`plan_worlds`)."""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from ._warp_private import private_api

__all__ = ["plan_worlds", "ONLY_WITH_FLAG"]

_IGNORED = {"name_", "names", "text", "stat", "paths", "signature"}


def _array_fields(mjm: mujoco.MjModel) -> list[str]:
    out = []
    for name in dir(mjm):
        if name.startswith("_") or any(name.startswith(p) for p in _IGNORED):
            continue
        try:
            v = getattr(mjm, name)
        except Exception:  # noqa: BLE001
            continue
        if isinstance(v, np.ndarray) and v.dtype.kind in "fiub":
            out.append(name)
    return out


_OPT_FIELDS = ("timestep", "tolerance", "ls_tolerance", "noslip_tolerance", "ccd_tolerance", "gravity",
               "wind", "magnetic", "density", "viscosity", "impratio", "o_margin", "o_solref", "o_solimp",
               "o_friction", "integrator", "cone", "jacobian", "solver", "iterations", "ls_iterations",
               "noslip_iterations", "ccd_iterations", "disableflags", "enableflags")


#: MjModel fields MuJoCo Warp reads only for a feature that an ``opt.enableflags`` bit turns on: where
#: every world leaves the bit off, the worlds need not agree on them (the Warp model carries the first
#: world's).  ``dof_length`` (the velocity norm's weights) is read by island sleeping alone
#: (mujoco_warp/_src/sleep.py; checked against the installed sources in tests/test_warp.py), and it
#: differs by ~1e-17 between pair scenes that differ in their start offset dx0: counted, it would split
#: every dx0 sweep into ~5 Warp models (as measured in an H200's quick reproduction, docs/gpu.md).
ONLY_WITH_FLAG = {"dof_length": int(mujoco.mjtEnableBit.mjENBL_SLEEP)}


def plan_worlds(models: Sequence[mujoco.MjModel]):
    """Split the worlds into groups that share one Warp model: worlds of a group differ only in
    fields that MuJoCo Warp batches per world.  Returns ``[(indices, {field: per-world values})]``
    (option fields under ``"opt." + name``).  MjModel fields MuJoCo Warp does not carry are ignored,
    and so are those it reads only for a feature every world leaves off (:data:`ONLY_WITH_FLAG`).
    Which fields MuJoCo Warp carries and batches: :func:`undulate.simulation._warp_private.private_api`."""
    api = private_api()
    known = set(api.model_fields)  # MjModel fields MuJoCo Warp does not carry (bvh_aabb...) do not matter
    flags = [int(m.opt.enableflags) for m in models]
    known -= {n for n, bit in ONLY_WITH_FLAG.items() if not any(f & bit for f in flags)}
    batchable, opt_batchable = api.per_world_model_fields, api.per_world_option_fields
    m0 = models[0]
    fields = _array_fields(m0)
    differ: dict[str, np.ndarray] = {}
    for name in fields:
        if name not in known:
            continue
        vals = [getattr(m, name) for m in models]
        ref, shape = vals[0].tobytes(), vals[0].shape  # equal bytes of one shape: equal values (NaN too)
        if not all(v.shape == shape and v.tobytes() == ref for v in vals[1:]):
            differ[name] = np.stack(vals)
    opt_differ: dict[str, np.ndarray] = {}
    for name in _OPT_FIELDS:
        vals = [np.asarray(getattr(m.opt, name)) for m in models]
        if not all(np.array_equal(v, vals[0]) for v in vals[1:]):
            opt_differ[name] = np.stack(vals)
    split = [n for n in differ if n not in batchable] + [f"opt.{n}" for n in opt_differ if n not in opt_batchable]
    # worlds that agree on every field that cannot be batched share one Warp model
    keys = []
    for b in range(len(models)):
        parts = [differ[n][b].tobytes() for n in split if not n.startswith("opt.")]
        parts += [opt_differ[n[4:]][b].tobytes() for n in split if n.startswith("opt.")]
        keys.append(b"|".join(parts))
    groups = []
    for key in dict.fromkeys(keys):
        idx = np.array([b for b, k in enumerate(keys) if k == key])
        per_world = {n: v[idx] for n, v in differ.items() if n in batchable}
        per_world.update({f"opt.{n}": v[idx] for n, v in opt_differ.items() if n in opt_batchable})
        groups.append((idx, per_world))
    return groups
