"""Typed sweep points of the three study runners.

A sweep's grid hands each run a plain mapping (its identity is that mapping,
hashed).  The runners turn it into one of these frozen types first, so an
unknown or mistyped key fails with one line naming it, in every runner alike,
and the model objects (:class:`~undulate.params.Gait`,
:class:`~undulate.params.Servo`, ...) are built in one place.  A field left
``None`` means "not given": the runner's or the model's default applies.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from ..errors import ParameterError
from ..params import GROUND_MODES, ContactModel, Gait, Ground, Servo, SwimmerGeometry

__all__ = ["GroupPoint", "PairPoint", "LonePoint", "PackingPoint", "SyncPoint", "MODEL_KEYS"]

MODEL_KEYS = ("kp_Nm_per_rad", "torque_limit_Nm", "max_speed_rad_s", "contact_timeconst_s", "drag_N_s_per_m")
"""Optional keys that change one model choice (the sensitivity study): servo gain, torque limit,
top speed (slew limit), contact time constant (s; 0 = the default, two time steps), linear drag."""


class _Point:
    """Shared parsing: :meth:`of` checks the keys and converts each value to its field's type."""

    _kinds: ClassVar[dict[str, type]] = {}

    @classmethod
    def of(cls, point: Mapping[str, Any] | "_Point"):
        """The typed point of a sweep point (a mapping of field names to values)."""
        if isinstance(point, cls):
            return point
        names = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(set(point) - set(names))
        if unknown:
            raise ParameterError("point", f"keys among {tuple(names)}", unknown)
        return cls(**{k: cls._convert(k, v) for k, v in point.items()})

    @classmethod
    def _convert(cls, key: str, value: Any) -> Any:
        kind = cls._kinds.get(key, float)
        try:
            if kind is bool:
                if not isinstance(value, (bool, int, np.bool_, np.integer)):
                    raise TypeError
                return bool(value)
            if kind is str and not isinstance(value, str):
                raise TypeError
            if kind is int and float(value) != int(value):
                raise ValueError
            return kind(value)
        except (TypeError, ValueError):
            raise ParameterError(key, f"a {kind.__name__}", value) from None

    def _model_parts(self) -> dict[str, Any]:
        """Scene keyword arguments for the :data:`MODEL_KEYS` given (others: defaults)."""
        servo = {k: getattr(self, k) for k in ("kp_Nm_per_rad", "torque_limit_Nm", "max_speed_rad_s")
                 if getattr(self, k, None) is not None}
        out: dict[str, Any] = {}
        if servo:
            out["servo"] = Servo(**servo)
        tc = getattr(self, "contact_timeconst_s", None)
        if tc is not None and tc > 0:
            out["contact"] = ContactModel(timeconst_s=tc)
        if getattr(self, "drag_N_s_per_m", None) is not None:
            out["ground"] = Ground(drag_N_s_per_m=self.drag_N_s_per_m)
        return out


@dataclasses.dataclass(frozen=True)
class GroupPoint(_Point):
    """A point of :func:`~undulate.studies._runners.group_point`: swimmers side by side from straight."""

    dphi_rad: float = 0.0
    """Phase step between neighbours in the initial stack, rad (swimmer j gets j dphi)."""
    waves_per_body: float = 1.0
    """xi."""
    n_links: int = 3
    amplitude_rad: float = math.radians(45.0)
    """beta, rad."""
    timestep_s: float | None = None
    """Integrator step, s (None: the runner's)."""
    heading_guide: bool = False
    """:attr:`~undulate.params.Scene.heading_guide`."""
    kp_Nm_per_rad: float | None = None
    torque_limit_Nm: float | None = None
    max_speed_rad_s: float | None = None
    contact_timeconst_s: float | None = None
    drag_N_s_per_m: float | None = None
    beta_rule: str | None = None
    """A label only (the links study's amplitude rule that chose ``amplitude_rad``): no effect on the run."""

    _kinds: ClassVar[dict[str, type]] = {"n_links": int, "heading_guide": bool, "beta_rule": str}

    def gait(self) -> Gait:
        return Gait(amplitude_rad=self.amplitude_rad, waves_per_body=self.waves_per_body)

    def model_parts(self) -> dict[str, Any]:
        """Scene keyword arguments for the model choices given (servo, contact, ground)."""
        return self._model_parts()


@dataclasses.dataclass(frozen=True)
class PairPoint(_Point):
    """A point of :func:`~undulate.studies._runners.pair_scene` (see there for each key)."""

    dx0_over_lambda: float = 0.0
    dphi_rad: float = 0.0
    phi0_rad: float = 0.0
    channel_width_m: float | None = None
    d_over_2A: float | None = None
    amplitude_m: float | None = None
    amplitude_rad: float | None = None
    force_N: float = 0.0
    ground: str = "viscous"
    waves_per_body: float = 1.0
    body_width_m: float | None = None
    fluid_density_kg_m3: float | None = None
    swim_drag_N_s_per_m: float | None = None
    drag_N_s_per_m: float | None = None

    _kinds: ClassVar[dict[str, type]] = {"ground": str}

    def __post_init__(self):
        if self.ground not in GROUND_MODES:
            raise ParameterError("ground", "'viscous', 'resistive' or 'swimming'", self.ground)
        if self.ground == "swimming" and self.drag_N_s_per_m is not None:
            raise ParameterError("drag_N_s_per_m", "the viscous ground's drag (use swim_drag_N_s_per_m for the "
                                 "swimming ground)", self.drag_N_s_per_m)

    def gait(self) -> Gait:
        beta = Gait().amplitude_rad if self.amplitude_rad is None else self.amplitude_rad
        return Gait(amplitude_rad=beta, waves_per_body=self.waves_per_body)

    def geometry(self) -> SwimmerGeometry:
        return SwimmerGeometry() if self.body_width_m is None else SwimmerGeometry(width_m=self.body_width_m)

    def ground_model(self) -> Ground:
        if self.ground == "swimming":
            kw = {"fluid_density_kg_m3": self.fluid_density_kg_m3, "drag_N_s_per_m": self.swim_drag_N_s_per_m}
            return Ground.swimming(**{k: v for k, v in kw.items() if v is not None})
        if self.ground == "resistive":  # drag_N_s_per_m, if given: the tangential coefficient c_par
            return Ground.resistive(**({} if self.drag_N_s_per_m is None else {"drag_N_s_per_m": self.drag_N_s_per_m}))
        return self._model_parts().get("ground", Ground())


@dataclasses.dataclass(frozen=True)
class LonePoint(_Point):
    """A point of :func:`~undulate.studies._runners.lone_swimmer`: one free swimmer."""

    amplitude_rad: float | None = None
    waves_per_body: float = 1.0
    n_links: int = 3
    ground: str = "viscous"
    heading_guide: bool = False

    _kinds: ClassVar[dict[str, type]] = {"n_links": int, "ground": str, "heading_guide": bool}

    def __post_init__(self):
        if self.ground not in GROUND_MODES:
            raise ParameterError("ground", "'viscous', 'resistive' or 'swimming'", self.ground)

    def ground_model(self) -> Ground:
        """The ground of ``ground``: :class:`Ground`, :meth:`Ground.resistive` or :meth:`Ground.swimming`."""
        return {"viscous": Ground, "resistive": Ground.resistive, "swimming": Ground.swimming}[self.ground]()

    def gait(self) -> Gait:
        beta = Gait().amplitude_rad if self.amplitude_rad is None else self.amplitude_rad
        return Gait(amplitude_rad=beta, waves_per_body=self.waves_per_body)


@dataclasses.dataclass(frozen=True)
class PackingPoint(_Point):
    """A point of :func:`~undulate.studies.packing.packing_point`: one pack of the packing grid."""

    phi_max_rad: float
    """Phase spread: phases uniform in [0, phi_max], rad."""
    rho_tilde: float
    """Dimensionless density 2 A N / Y."""
    draw: int
    """Index of the phase draw (with the study's base seed, the random stream)."""

    _kinds: ClassVar[dict[str, type]] = {"draw": int}

    def __post_init__(self):
        if not self.rho_tilde > 0:
            raise ParameterError("rho_tilde", "> 0", self.rho_tilde)


@dataclasses.dataclass(frozen=True)
class SyncPoint(_Point):
    """A point of the synchronization studies' runners (pairs: ``hold_x``, ``dphi0_rad``;
    groups: ``n_swimmers``, ``spacing_m``; the free frequency: ``controller`` only)."""

    controller: str
    """A key of :data:`undulate.studies.synchronization.CONTROLLERS`."""
    hold_x: bool = False
    dphi0_rad: float = 0.0
    """Initial phi_1 - phi_0, rad."""
    n_swimmers: int = 2
    spacing_m: float | None = None
    """Channel width per swimmer, m."""

    _kinds: ClassVar[dict[str, type]] = {"controller": str, "hold_x": bool, "n_swimmers": int}
