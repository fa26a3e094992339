"""Per-joint calibration and safety limits, from a small TOML file.

Example (every key optional; angles in degrees, speeds in degrees per second,
as a bench user measures them; stored in SI inside)::

    servo = "AX-12A"                # servo model (default: AX-12A on protocol 1, XL430-W250 on 2)
    joint_limit_deg = [-90, 90]     # default joint limits for every joint
    max_speed_deg_s = 300           # maximum commanded joint speed
    homing_speed_deg_s = 60         # speed of the move to the gait's first pose
    stall_torque_Nm = 1.5           # present load 100 % = this torque (default: the model's)
    load_sign = 1                   # -1 flips the sign of present load

    [[joint]]
    id = 3                          # servo id
    offset_ticks = -7               # ticks of the straight pose relative to the centre (512 / 2048)
    sign = -1                       # -1: a positive joint angle maps below the centre
    limit_deg = [-60, 80]           # this joint's limits (override joint_limit_deg)

An id without a ``[[joint]]`` entry gets offset 0, sign +1 and the default
limits.  Unknown keys are refused (a misspelt key would silently do nothing).
"""

from __future__ import annotations

import hashlib
import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ParameterError

__all__ = ["JointCalibration", "Calibration", "load_calibration"]


@dataclass(frozen=True)
class JointCalibration:
    """One servo's mapping between joint angle and ticks, and its limits (rad)."""

    id: int
    offset_ticks: int = 0
    sign: int = 1
    lower_rad: float = -math.pi / 2
    upper_rad: float = math.pi / 2


@dataclass(frozen=True)
class Calibration:
    """Calibration of every servo on the bus plus the run's safety limits (SI)."""

    joints: tuple[JointCalibration, ...] = ()
    default_lower_rad: float = -math.pi / 2
    default_upper_rad: float = math.pi / 2
    max_speed_rad_s: float = math.radians(300.0)
    homing_speed_rad_s: float = math.radians(60.0)
    servo: str | None = None
    stall_torque_Nm: float | None = None
    load_sign: int = 1
    source: str = "defaults (no calibration file)"
    sha256: str = ""
    by_id: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "by_id", {j.id: j for j in self.joints})

    def joint(self, servo_id: int) -> JointCalibration:
        """The calibration of ``servo_id`` (defaults when the file does not list it)."""
        j = self.by_id.get(servo_id)
        if j is None:
            return JointCalibration(servo_id, 0, 1, self.default_lower_rad, self.default_upper_rad)
        return j

    def to_dict(self) -> dict:
        return {
            "source": self.source, "sha256": self.sha256, "servo": self.servo,
            "default_limits_rad": [self.default_lower_rad, self.default_upper_rad],
            "max_speed_rad_s": self.max_speed_rad_s, "homing_speed_rad_s": self.homing_speed_rad_s,
            "stall_torque_Nm": self.stall_torque_Nm, "load_sign": self.load_sign,
            "joints": [j.__dict__ for j in self.joints],
        }

    def to_json(self) -> str:
        return json.dumps(self.to_dict())


_TOP = {"servo", "joint_limit_deg", "max_speed_deg_s", "homing_speed_deg_s", "stall_torque_Nm", "load_sign", "joint"}
_JOINT = {"id", "offset_ticks", "sign", "limit_deg"}


def _limits(name: str, v) -> tuple[float, float]:
    if (not isinstance(v, list) or len(v) != 2 or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                           for x in v)):
        raise ParameterError(name, "[lower, upper] in degrees", v)
    lo, hi = float(v[0]), float(v[1])
    if not (-150.0 <= lo <= 0.0 <= hi <= 150.0) or lo == hi:
        raise ParameterError(name, "lower <= 0 <= upper within [-150, 150] degrees", v)
    return math.radians(lo), math.radians(hi)


def _positive(name: str, v, upper: float) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not (0 < float(v) <= upper):
        raise ParameterError(name, f"a number in (0, {upper:g}]", v)
    return float(v)


def load_calibration(path: str | Path | None) -> Calibration:
    """Read and validate a calibration file (``None``: the defaults).

    Raises :class:`~undulate.errors.ParameterError` naming the file and key.
    """
    if path is None:
        return Calibration()
    path = Path(path)
    where = f"--calibration {path}"
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise ParameterError("--calibration", "a readable TOML file", f"{path} ({e.strerror})") from None
    try:
        d = tomllib.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise ParameterError("--calibration", "a valid TOML file", f"{path}: {e}") from None
    unknown = sorted(set(d) - _TOP)
    if unknown:
        raise ParameterError(f"{where}: key {unknown[0]!r}", "one of " + ", ".join(sorted(_TOP)))
    kw: dict = {"source": str(path), "sha256": hashlib.sha256(raw).hexdigest()}
    if "servo" in d:
        from .servos import SERVO_MODELS, servo_model

        try:
            kw["servo"] = servo_model(d["servo"]).name
        except KeyError:
            raise ParameterError(f"{where}: servo", "one of " + ", ".join(SERVO_MODELS), d["servo"]) from None
    lo, hi = -math.pi / 2, math.pi / 2
    if "joint_limit_deg" in d:
        lo, hi = _limits(f"{where}: joint_limit_deg", d["joint_limit_deg"])
    kw["default_lower_rad"], kw["default_upper_rad"] = lo, hi
    if "max_speed_deg_s" in d:
        kw["max_speed_rad_s"] = math.radians(_positive(f"{where}: max_speed_deg_s", d["max_speed_deg_s"], 1000.0))
    if "homing_speed_deg_s" in d:
        kw["homing_speed_rad_s"] = math.radians(_positive(f"{where}: homing_speed_deg_s", d["homing_speed_deg_s"],
                                                          1000.0))
    if "stall_torque_Nm" in d:
        kw["stall_torque_Nm"] = _positive(f"{where}: stall_torque_Nm", d["stall_torque_Nm"], 100.0)
    if "load_sign" in d:
        if d["load_sign"] not in (1, -1) or isinstance(d["load_sign"], bool):
            raise ParameterError(f"{where}: load_sign", "1 or -1", d["load_sign"])
        kw["load_sign"] = int(d["load_sign"])
    joints = []
    entries = d.get("joint", [])
    if not isinstance(entries, list):
        raise ParameterError(f"{where}: joint", "[[joint]] tables", entries)
    for n, e in enumerate(entries):
        if not isinstance(e, dict):
            raise ParameterError(f"{where}: joint #{n + 1}", "a [[joint]] table", e)
        bad = sorted(set(e) - _JOINT)
        if bad:
            raise ParameterError(f"{where}: joint #{n + 1} key {bad[0]!r}", "one of " + ", ".join(sorted(_JOINT)))
        sid = e.get("id")
        if isinstance(sid, bool) or not isinstance(sid, int) or not 0 <= sid <= 252:
            raise ParameterError(f"{where}: joint #{n + 1} id", "an integer servo id in [0, 252]", sid)
        if any(j.id == sid for j in joints):
            raise ParameterError(f"{where}: joint id {sid}", "listed once", "duplicate")
        off = e.get("offset_ticks", 0)
        if isinstance(off, bool) or not isinstance(off, int) or abs(off) > 2048:
            raise ParameterError(f"{where}: joint id {sid} offset_ticks", "an integer in [-2048, 2048]", off)
        sign = e.get("sign", 1)
        if isinstance(sign, bool) or sign not in (1, -1):
            raise ParameterError(f"{where}: joint id {sid} sign", "1 or -1", sign)
        jlo, jhi = _limits(f"{where}: joint id {sid} limit_deg", e["limit_deg"]) if "limit_deg" in e else (lo, hi)
        joints.append(JointCalibration(sid, int(off), int(sign), jlo, jhi))
    kw["joints"] = tuple(joints)
    cal = Calibration(**kw)
    if cal.homing_speed_rad_s > cal.max_speed_rad_s:
        raise ParameterError(f"{where}: homing_speed_deg_s", f"<= max_speed_deg_s ({math.degrees(cal.max_speed_rad_s):g})",
                             math.degrees(cal.homing_speed_rad_s))
    return cal
