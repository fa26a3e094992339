"""Servo models: control-table addresses, ranges and every unit conversion, in one place.

Addresses and units are ROBOTIS's (e-Manual control tables):

=====================  =================================  ==================================
                       AX-12A / AX-18A (Protocol 1.0)     XL430-W250 (Protocol 2.0)
=====================  =================================  ==================================
model number           0 (2 B): 12 / 18                   0 (2 B): 1060
torque enable          24 (1 B)                           64 (1 B)
goal position          30 (2 B), 0..1023                  116 (4 B), 0..4095
moving speed           32 (2 B) moving speed,             112 (4 B) profile velocity,
                       0.111 rev/min, 0 = no limit        0.229 rev/min, 0 = no limit
present position       36 (2 B)                           132 (4 B, signed)
present speed          38 (2 B), sign-magnitude (bit 10)  128 (4 B, signed), 0.229 rev/min
present load           40 (2 B), sign-magnitude (bit 10   126 (2 B, signed), 0.1 % per unit
                       = CW), about 0.1 % per unit
position range         1024 ticks over 300 deg, centre    4096 ticks over 360 deg, centre
                       512                                2048
mode check             CW/CCW angle limits 6, 8 (both 0:  operating mode 11 (3: position)
                       wheel mode)
=====================  =================================  ==================================

Angles: ``ticks = centre + offset_ticks + sign * angle_rad / rad_per_tick``
(a positive joint angle maps above the centre without a calibration).

**Present load -> N m.**  Both families report the motor's output as a
fraction of its maximum torque, 0.1 % per unit (AX: magnitude in bits 0-9,
bit 10 set for the clockwise direction; X: two's complement, positive
counter-clockwise).  We take "maximum torque" as the stall torque of the
servo model (AX-12A 1.5 N m at 12 V, AX-18A 1.8 N m at 12 V, XL430-W250
1.4 N m at 11.1 V; overridable in the calibration file) and the
counter-clockwise (increasing-tick) direction as positive, so::

    load_Nm = sign * load_sign * (raw_fraction) * stall_torque_Nm

with ``sign`` the joint's direction in the calibration.  ROBOTIS notes the
value is inferred from the motor drive, not measured by a torque sensor: it
is the quantity the simulation's ``actuatorfrc`` models, not a calibrated
torque.  ``load_sign`` (calibration file) flips the convention should a
check on hardware show the opposite sign (docs/robots.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ServoModel", "SERVO_MODELS", "DEFAULT_SERVO", "servo_model"]

_RPM = 2 * math.pi / 60.0  # rad/s per rev/min


@dataclass(frozen=True)
class ServoModel:
    """One Dynamixel model: protocol, control-table layout, ranges, units."""

    name: str
    protocol: int
    model_number: int
    resolution_ticks: int
    """Ticks over the position range (1024 AX, 4096 X)."""
    range_deg: float
    """Angle spanned by ``resolution_ticks``, deg (300 AX, 360 X)."""
    centre_ticks: int
    speed_unit_rpm: float
    """Moving speed / profile velocity / present speed unit, rev/min."""
    speed_register_max: int
    no_load_speed_rpm: float
    stall_torque_Nm: float
    addr_torque_enable: int
    addr_goal: int
    """Start of the per-tick write block (AX: goal position + moving speed; X: profile velocity + goal position)."""
    write_size: int
    addr_present: int
    """Start of the per-tick read block (AX: position, speed, load; X: load, velocity, position)."""
    present_size: int

    @property
    def rad_per_tick(self) -> float:
        return math.radians(self.range_deg) / self.resolution_ticks

    @property
    def max_tick(self) -> int:
        return self.resolution_ticks - 1

    @property
    def no_load_speed_rad_s(self) -> float:
        return self.no_load_speed_rpm * _RPM

    # --- conversions (vectorised over joints) --------------------------------------------------
    def angle_to_ticks(self, angle_rad, offset_ticks, sign) -> np.ndarray:
        """Joint angle (rad) -> goal position (int ticks), not clipped."""
        return np.rint(self.centre_ticks + np.asarray(offset_ticks) + np.asarray(sign) * np.asarray(angle_rad)
                       / self.rad_per_tick).astype(np.int64)

    def ticks_to_angle(self, ticks, offset_ticks, sign) -> np.ndarray:
        """Present position (ticks) -> joint angle (rad)."""
        return np.asarray(sign) * (np.asarray(ticks, dtype=float) - self.centre_ticks - np.asarray(offset_ticks)) \
            * self.rad_per_tick

    def speed_to_register(self, speed_rad_s) -> np.ndarray:
        """Joint speed magnitude (rad/s) -> moving speed / profile velocity register, >= 1 (0 means no limit)."""
        units = np.rint(np.abs(np.asarray(speed_rad_s, dtype=float)) / (self.speed_unit_rpm * _RPM))
        return np.clip(units, 1, self.speed_register_max).astype(np.int64)

    def register_to_speed(self, units) -> np.ndarray:
        """Moving speed register -> rad/s."""
        return np.asarray(units, dtype=float) * self.speed_unit_rpm * _RPM

    def decode_speed(self, raw: int) -> float:
        """Present speed register -> signed speed in ticks' direction, rad/s."""
        if self.protocol == 1:
            mag = raw & 0x3FF
            return (-mag if raw & 0x400 else mag) * self.speed_unit_rpm * _RPM
        return _signed(raw, 32) * self.speed_unit_rpm * _RPM

    def decode_load(self, raw: int) -> float:
        """Present load register -> signed fraction of the maximum torque (+: toward increasing ticks)."""
        if self.protocol == 1:
            mag = raw & 0x3FF  # sign-magnitude: bit 10 is the direction (1: CW, decreasing ticks)
            return (-mag if raw & 0x400 else mag) * 1e-3
        return _signed(raw, 16) * 1e-3

    def decode_present(self, data) -> tuple[int, float, float]:
        """The per-tick read block (bytes) -> (position ticks, speed rad/s, load fraction)."""
        b = bytes(data)
        if self.protocol == 1:  # 36: position, 38: speed, 40: load (2 B each)
            pos = b[0] | b[1] << 8
            return pos, self.decode_speed(b[2] | b[3] << 8), self.decode_load(b[4] | b[5] << 8)
        load = b[0] | b[1] << 8  # 126: load (2 B), 128: velocity (4 B), 132: position (4 B)
        vel = int.from_bytes(b[2:6], "little")
        pos = _signed(int.from_bytes(b[6:10], "little"), 32)
        return pos, self.decode_speed(vel), self.decode_load(load)

    def encode_write(self, goal_ticks: int, speed_units: int) -> list[int]:
        """The per-tick write block for one servo, little endian."""
        if self.protocol == 1:  # 30: goal position, 32: moving speed
            return list(int(goal_ticks).to_bytes(2, "little")) + list(int(speed_units).to_bytes(2, "little"))
        return list(int(speed_units).to_bytes(4, "little")) + list(int(goal_ticks).to_bytes(4, "little"))


def _signed(v: int, bits: int) -> int:
    v &= (1 << bits) - 1
    return v - (1 << bits) if v >> (bits - 1) else v


_AX = dict(protocol=1, resolution_ticks=1024, range_deg=300.0, centre_ticks=512, speed_unit_rpm=0.111,
           speed_register_max=1023, addr_torque_enable=24, addr_goal=30, write_size=4, addr_present=36,
           present_size=6)
_X = dict(protocol=2, resolution_ticks=4096, range_deg=360.0, centre_ticks=2048, speed_unit_rpm=0.229,
          speed_register_max=32767, addr_torque_enable=64, addr_goal=112, write_size=8, addr_present=126,
          present_size=10)

SERVO_MODELS: dict[str, ServoModel] = {
    m.name: m for m in (
        ServoModel("AX-12A", model_number=12, no_load_speed_rpm=59.0, stall_torque_Nm=1.5, **_AX),
        ServoModel("AX-18A", model_number=18, no_load_speed_rpm=97.0, stall_torque_Nm=1.8, **_AX),
        ServoModel("XL430-W250", model_number=1060, no_load_speed_rpm=57.0, stall_torque_Nm=1.4, **_X),
    )
}
DEFAULT_SERVO = {1: "AX-12A", 2: "XL430-W250"}


def servo_model(name: str) -> ServoModel:
    """Look a model up by name (case-insensitive)."""
    for k, m in SERVO_MODELS.items():
        if k.lower() == str(name).lower():
            return m
    raise KeyError(name)
