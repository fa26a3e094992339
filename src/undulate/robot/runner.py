"""Drive real servos with the controllers of :mod:`undulate.control` and log the run.

One control tick (every ``1 / control_rate_hz``, on an absolute schedule from
the gait's t = 0):

1. the controller gets the last sensed joint angles (rad), speeds (rad/s)
   and loads (N m) and returns the set-points at ``t_k`` and ``t_k + dt``
   -- the very objects :func:`undulate.simulation.simulate` steps;
2. safety, before anything reaches a servo: joint limits clip the set-points,
   then a slew limit keeps consecutive goals within ``max_speed * elapsed``;
3. ONE sync write sends every servo its goal for ``t_k + dt`` and the moving
   speed that gets it there by then (so the servo follows the piecewise-linear
   set-point, as the simulation's servo does between control updates);
4. every servo's present position, speed and load are read (Protocol 1: servo
   by servo; Protocol 2: one sync read); a time-out gives NaN for that servo
   in the log and the controller keeps its last good reading.

Before the gait: the servos are pinged and their model and mode checked,
each goal is set to its present position, torque is enabled (confirmed per
servo) and the joints move to the gait's first pose at the homing speed.

Torque goes off on every exit path: normal end, exception, Ctrl-C (SIGINT),
SIGTERM and SIGHUP (turned into :class:`Interrupted` while the run is
active; deferred while torque goes off and the log is written), a servo that
stops answering for ``max_silence_s`` (torque off on all the others), a
servo hardware fault, and a lost port (the port is reopened by name for up
to 2 s -- an adapter that re-enumerates under a stable ``/dev/serial/by-id``
link comes back -- and the report says which servos could not be switched
off).  Torque-off is one broadcast SYNC_WRITE then a confirmed WRITE per
servo.  A SIGKILL or a host power cut cannot be handled: the servos then hold
their last goal (docs/robots.md).
"""

from __future__ import annotations

import json
import math
import signal
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..control import Controller, make_controller
from ..errors import ParameterError, UndulateError
from ..params import Scene
from .bus import BusError, BusLost, DynamixelBus, ServoFault, ServoSetupError, ServoSilent
from .calibration import Calibration
from .servos import DEFAULT_SERVO, SERVO_MODELS, ServoModel, servo_model

__all__ = ["RobotConfig", "Interrupted", "run_robot", "dry_run", "schedule_text", "ping", "BAUDRATES"]

BAUDRATES = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600, 1000000, 1152000,
             2000000, 2500000, 3000000, 3500000, 4000000)  # what dynamixel-sdk's PortHandler accepts


class Interrupted(BaseException):
    """A signal (SIGINT, SIGTERM, SIGHUP) ended the run."""

    def __init__(self, signum: int):
        self.signum = int(signum)
        super().__init__(signal.Signals(signum).name)


@dataclass(frozen=True)
class RobotConfig:
    """A robot run: the scene (gait, phases, links, controller) on servos ``ids``.

    ``ids``: servo ids robot by robot, head joint first (robot 0's joints, then
    robot 1's, ...); their count is ``n_robots * (n_links - 1)`` with one robot
    per phase in ``scene.phases_rad``.  ``scene.controller.control_rate_hz`` is
    the bus control rate.  Everything is validated here, before any port is
    opened (:class:`~undulate.errors.ParameterError` naming the field).
    """

    scene: Scene
    ids: tuple[int, ...]
    protocol: int = 1
    port: str | None = None
    baudrate: int = 1_000_000
    duration_s: float = 30.0
    calibration: Calibration = field(default_factory=Calibration)
    servo: str | None = None
    """Servo model name (default: the calibration's, else AX-12A on protocol 1, XL430-W250 on 2)."""
    max_silence_s: float = 1.0
    """A servo that has not answered for this long ends the run, s."""

    def __post_init__(self):
        if self.protocol not in (1, 2) or isinstance(self.protocol, bool):
            raise ParameterError("protocol", "1 (AX series) or 2 (X series)", self.protocol)
        if self.baudrate not in BAUDRATES:
            raise ParameterError("baudrate", "one of " + ", ".join(map(str, BAUDRATES)) + " bit/s", self.baudrate)
        name = self.servo or self.calibration.servo or DEFAULT_SERVO[self.protocol]
        try:
            model = servo_model(name)
        except KeyError:
            raise ParameterError("servo", "one of " + ", ".join(SERVO_MODELS), name) from None
        if model.protocol != self.protocol:
            raise ParameterError("servo", f"a protocol {self.protocol} model (the {model.name} speaks protocol "
                                 f"{model.protocol})", model.name)
        object.__setattr__(self, "servo", model.name)
        ids = tuple(self.ids)
        n_links = self.scene.geometry.n_links
        want = self.scene.n_swimmers * (n_links - 1)
        if len(ids) != want:
            raise ParameterError("ids", f"{want} servo ids ({self.scene.n_swimmers} robot(s) x {n_links - 1} joints, "
                                 "robot by robot, head joint first)", ",".join(map(str, ids)))
        top = 253 if self.protocol == 1 else 252
        for i in ids:
            if isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 0 <= i <= top:
                raise ParameterError("ids", f"integers in [0, {top}]", i)
        if len(set(ids)) != len(ids):
            raise ParameterError("ids", "distinct servo ids", ",".join(map(str, ids)))
        object.__setattr__(self, "ids", tuple(int(i) for i in ids))
        d = self.duration_s
        if isinstance(d, bool) or not isinstance(d, (int, float)) or not math.isfinite(d) or not 0 < d <= 86400:
            raise ParameterError("duration_s", "in (0, 86400] s", d)
        rate = self.scene.controller.control_rate_hz
        if rate > 500:
            raise ParameterError("control_rate_hz", "in (0, 500] Hz on a servo bus", rate)
        if not (isinstance(self.max_silence_s, (int, float)) and 0 < self.max_silence_s <= 60):
            raise ParameterError("max_silence_s", "in (0, 60] s", self.max_silence_s)
        # every commanded tick must exist on the servo: the gait's range after limits and calibration
        beta = self.scene.gait.amplitude_rad
        lo, hi = np.maximum(-beta, self.lower_rad), np.minimum(beta, self.upper_rad)
        for a in (lo, hi):
            t = model.angle_to_ticks(a, self.offsets, self.signs)
            bad = np.argwhere((t < 0) | (t > model.max_tick))
            if bad.size:
                j = tuple(bad[0])
                raise ParameterError(
                    "amplitude_rad", f"within the {model.name}'s range (0..{model.max_tick} ticks): joint "
                    f"{j[1]} of robot {j[0]} (id {self.id_grid[j]}) would be sent {int(t[j])} ticks",
                    f"{math.degrees(beta):g} deg")
        peak = 2 * math.pi * self.scene.gait.frequency_hz * beta
        if peak > self.calibration.max_speed_rad_s * (1 + 1e-12):
            raise ParameterError("frequency_hz", f"such that the gait's peak joint speed 2 pi f beta = "
                                 f"{math.degrees(peak):.0f} deg/s <= the maximum commanded speed "
                                 f"{math.degrees(self.calibration.max_speed_rad_s):g} deg/s", self.scene.gait.frequency_hz)

    # --- derived -----------------------------------------------------------------------------
    @property
    def model(self) -> ServoModel:
        return SERVO_MODELS[self.servo]

    @property
    def shape(self) -> tuple[int, int]:
        return self.scene.n_swimmers, self.scene.geometry.n_links - 1

    @property
    def id_grid(self) -> np.ndarray:
        """Servo ids, shape (robot, joint)."""
        return np.array(self.ids, dtype=np.int64).reshape(self.shape)

    def _per_joint(self, attr: str) -> np.ndarray:
        return np.array([getattr(self.calibration.joint(i), attr) for i in self.ids]).reshape(self.shape)

    @property
    def offsets(self) -> np.ndarray:
        return self._per_joint("offset_ticks")

    @property
    def signs(self) -> np.ndarray:
        return self._per_joint("sign")

    @property
    def lower_rad(self) -> np.ndarray:
        return self._per_joint("lower_rad").astype(float)

    @property
    def upper_rad(self) -> np.ndarray:
        return self._per_joint("upper_rad").astype(float)

    @property
    def rate_hz(self) -> float:
        return self.scene.controller.control_rate_hz

    @property
    def n_ticks(self) -> int:
        return int(math.floor(self.duration_s * self.rate_hz + 1e-9)) + 1

    @property
    def stall_torque_Nm(self) -> float:
        return self.calibration.stall_torque_Nm or self.model.stall_torque_Nm

    def clipped_joints(self) -> list[str]:
        """Joints whose limits clip the gait (warnings, not errors: the limits win)."""
        beta = self.scene.gait.amplitude_rad
        out = []
        for (r, j), sid in np.ndenumerate(self.id_grid):
            lo, hi = self.lower_rad[r, j], self.upper_rad[r, j]
            if -beta < lo or beta > hi:
                out.append(f"id {sid} (robot {r} joint {j}): limits [{math.degrees(lo):g}, {math.degrees(hi):g}] deg "
                           f"clip the gait's +-{math.degrees(beta):g} deg")
        return out

    def to_dict(self) -> dict:
        return {"ids": self.id_grid.tolist(), "protocol": self.protocol, "port": self.port,
                "baudrate": self.baudrate, "duration_s": self.duration_s, "servo": self.servo,
                "max_silence_s": self.max_silence_s, "calibration": self.calibration.to_dict()}


# --- recording ---------------------------------------------------------------------------------


class _Recorder:
    """Rows of the log, preallocated for the whole run."""

    def __init__(self, cfg: RobotConfig):
        n, (r, j) = cfg.n_ticks, cfg.shape
        nan = lambda *s: np.full(s, np.nan)  # noqa: E731
        self.cfg = cfg
        self.k = np.zeros(n, dtype=np.int64)
        self.wall = nan(n)
        self.lateness = nan(n)
        self.command = nan(n, r, j)
        self.goal = nan(n, r, j)
        self.goal_ticks = np.zeros((n, r, j), dtype=np.int32)
        self.goal_speed = nan(n, r, j)
        self.angle = nan(n, r, j)
        self.velocity = nan(n, r, j)
        self.load = nan(n, r, j)
        self.ticks = nan(n, r, j)
        self.sense_t = nan(n, r, j)
        self.error = np.full((n, r, j), -1, dtype=np.int16)
        self.phase = nan(n, r)
        self.rows = 0
        self.notes: dict = {}

    def add(self, **row) -> None:
        i = self.rows
        for k, v in row.items():
            getattr(self, k)[i] = v
        self.rows += 1

    def dataset(self, *, end_reason: str, torque_off: str, dry: bool, ok: bool):
        """The recorded ticks as a Dataset (the simulation's schema where the names are shared)."""
        import xarray as xr

        cfg, n = self.cfg, self.rows
        sc = cfg.scene
        data = self._commanded_vars(n)
        if not dry:
            data.update(self._sensed_vars(n))
        coords = {
            "time": ("time", self.k[:n] * (1.0 / cfg.rate_hz), {"units": "s", "long_name": "time"}),
            "swimmer": ("swimmer", np.arange(cfg.shape[0])),
            "joint": ("joint", np.arange(cfg.shape[1])),
            "phase": ("swimmer", np.asarray(sc.phases_rad), {"units": "rad", "long_name": "gait phase phi"}),
            "servo_id": (("swimmer", "joint"), cfg.id_grid),
        }
        attrs = self._attrs(n, end_reason=end_reason, torque_off=torque_off, dry=dry, ok=ok)
        return xr.Dataset(data, coords=coords, attrs=attrs)

    def _commanded_vars(self, n: int) -> dict:
        """What was sent, in the first ``n`` rows: commands, phases, goals, and the tick timing."""
        import xarray as xr

        from ..schema import variable  # the simulation's schema: same names, dims, units

        dims3 = ("time", "swimmer", "joint")
        return {
            "joint_command": variable("joint_command", self.command[:n]),
            "gait_phase": variable("gait_phase", self.phase[:n]),
            "goal_position": xr.Variable(dims3, self.goal_ticks[:n], {
                "units": "ticks", "long_name": "goal position sent at this tick (the set-point for time + 1/control_rate)"}),
            "goal_angle": xr.Variable(dims3, self.goal[:n], {"units": "rad", "long_name": "joint angle of goal_position"}),
            "goal_speed": xr.Variable(dims3, self.goal_speed[:n], {
                "units": "rad/s", "long_name": "moving speed / profile velocity sent with the goal"}),
            "wall_clock": xr.Variable(("time",), self.wall[:n], {
                "units": "s", "long_name": "UNIX time (UTC seconds after 1970-01-01T00:00:00Z) when the tick's "
                "sync write went out"}),
            "tick_lateness": xr.Variable(("time",), self.lateness[:n], {
                "units": "s", "long_name": "start of the tick minus its scheduled time"}),
        }

    def _sensed_vars(self, n: int) -> dict:
        """What the servos reported, in the first ``n`` rows (not in a dry run)."""
        import xarray as xr

        from ..schema import variable

        dims3 = ("time", "swimmer", "joint")
        return {
            "joint_angle": variable("joint_angle", self.angle[:n]),
            "joint_error": variable("joint_error", np.abs(self.angle[:n] - self.command[:n])),
            "joint_velocity": xr.Variable(dims3, self.velocity[:n], {
                "units": "rad/s", "long_name": "present speed (servo's estimate)"}),
            "servo_load": xr.Variable(dims3, self.load[:n], {
                "units": "N m", "long_name": "present load as output torque: sign * load_sign * fraction * "
                "stall torque (undulate.robot.servos)"}),
            "present_position": xr.Variable(dims3, self.ticks[:n], {"units": "ticks", "long_name": "present position"}),
            "sense_time": xr.Variable(dims3, self.sense_t[:n], {
                "units": "s", "long_name": "gait time at which the reading was taken"}),
            "servo_error": xr.Variable(dims3, self.error[:n], {
                "units": "1", "long_name": "status packet error byte (-1: no reply)"}),
        }

    def _attrs(self, n: int, *, end_reason: str, torque_off: str, dry: bool, ok: bool) -> dict:
        """The run's attributes: scene, timing achieved, bus and servo settings, how it ended, provenance."""
        from ..provenance import package_version, provenance
        from ..schema import scene_attrs

        cfg = self.cfg
        sc = cfg.scene
        lat = self.lateness[:n]
        rate = (float((n - 1) / (self.wall[n - 1] - self.wall[0])) if n > 1 and not dry else float("nan"))
        config = {"scene": sc.to_dict(), "robot": cfg.to_dict()}
        prov = provenance()
        prov["dynamixel_sdk_version"] = package_version("dynamixel-sdk", "not installed")
        return {
            "title": "undulate robot dry run (commanded trajectory)" if dry else "undulate robot run",
            "source": "robot",
            **scene_attrs(sc),
            "sample_interval": 1.0 / cfg.rate_hz,
            "controller": sc.controller.kind,
            "control_rate": cfg.rate_hz,
            "control_rate_units": "Hz (nominal: the tick schedule)",
            "control_rate_achieved": rate,
            "tick_lateness_rms": float(np.sqrt(np.nanmean(lat ** 2))) if n and not dry else float("nan"),
            "tick_lateness_max": float(np.nanmax(lat)) if n and not dry else float("nan"),
            "tick_lateness_units": "s",
            "ticks_skipped": int(self.notes.get("skipped", 0)),
            "read_timeouts": int(self.notes.get("timeouts", 0)),
            "protocol": cfg.protocol,
            "baudrate": cfg.baudrate,
            "port": cfg.port or "",
            "servo_model": cfg.servo,
            "servo_stall_torque": cfg.stall_torque_Nm,
            "servo_stall_torque_units": "N m",
            "load_conversion": "servo_load = sign * load_sign * (present load fraction, 0.1 % per unit; AX "
                               "sign-magnitude with bit 10 = CW) * servo_stall_torque; + = toward increasing ticks",
            "calibration": cfg.calibration.to_json(),
            "end_reason": end_reason,
            "completed": int(ok),
            "torque_off": torque_off,
            "dry_run": int(dry),
            "conventions": "time: gait time t (s) of the tick; heads toward -x; joint i of robot j follows "
                           "beta sin(2 pi xi i / N - 2 pi f t + phi_j); positive angle = ticks above the centre "
                           "(times the calibration sign)",
            "config": json.dumps(config),
            **{f"provenance_{k}": v for k, v in prov.items()},
        }


# --- signals -----------------------------------------------------------------------------------

_SIGNALS = tuple(s for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)) if s is not None)


class _Signals:
    """While active, SIGINT/SIGTERM/SIGHUP raise :class:`Interrupted`; :meth:`defer` records them instead."""

    def __init__(self):
        self.main = threading.current_thread() is threading.main_thread()
        self.pending: int | None = None
        self.deferring = False
        self.saved = {}

    def _handler(self, signum, frame):
        if self.deferring:
            self.pending = self.pending or signum
            return
        raise Interrupted(signum)

    def __enter__(self):
        if self.main:
            for s in _SIGNALS:
                self.saved[s] = signal.signal(s, self._handler)
        return self

    def defer(self) -> None:
        self.deferring = True

    def __exit__(self, *exc):
        if self.main:
            for s, h in self.saved.items():
                signal.signal(s, h)
        return False


# --- the run -----------------------------------------------------------------------------------


class _ServoBus:
    """The servos of a run on a bus: units, limits, reads and writes."""

    def __init__(self, cfg: RobotConfig, bus: DynamixelBus):
        self.cfg, self.bus, self.m = cfg, bus, cfg.model
        self.ids = list(cfg.ids)
        self.off, self.sign = cfg.offsets, cfg.signs
        self.load_scale = cfg.signs * cfg.calibration.load_sign * cfg.stall_torque_Nm

    def check(self) -> None:
        """Every id answers with the expected model, in position mode; no torque is touched."""
        m = self.m
        missing, wrong = [], []
        for i in self.ids:
            num = self.bus.ping(i)
            if num is None:
                missing.append(i)
            elif num != m.model_number:
                wrong.append(f"id {i} is model {num}")
        if missing:
            raise ServoSetupError(f"servo id(s) {','.join(map(str, missing))} did not answer on {self.cfg.port} "
                                  f"(protocol {self.cfg.protocol}, {self.cfg.baudrate} bit/s)")
        if wrong:
            raise ServoSetupError(f"expected {m.name} (model {m.model_number}): " + "; ".join(wrong))
        # the ticks the gait will command, per servo (limits and calibration applied)
        beta = self.cfg.scene.gait.amplitude_rad
        ends = [m.angle_to_ticks(np.maximum(-beta, self.cfg.lower_rad), self.off, self.sign),
                m.angle_to_ticks(np.minimum(beta, self.cfg.upper_rad), self.off, self.sign)]
        lo_t, hi_t = np.minimum(*ends).ravel(), np.maximum(*ends).ravel()
        for n, i in enumerate(self.ids):
            if self.cfg.protocol == 1:
                d = self.bus.read(i, 6, 4)
                if d is None:
                    raise ServoSilent(f"servo id {i} did not answer a read of its angle limits")
                cw, ccw = d[0] | d[1] << 8, d[2] | d[3] << 8
                if cw == 0 and ccw == 0:
                    raise ServoSetupError(f"servo id {i} is in wheel mode (CW and CCW angle limits 0): set joint mode")
                if lo_t[n] < cw or hi_t[n] > ccw:
                    raise ServoSetupError(f"servo id {i}'s angle limits [{cw}, {ccw}] ticks would refuse the gait's "
                                          f"goals [{lo_t[n]}, {hi_t[n]}]: widen them or narrow limit_deg")
            else:
                d = self.bus.read(i, 10, 2)  # drive mode, operating mode
                if d is None:
                    raise ServoSilent(f"servo id {i} did not answer a read of its operating mode")
                if d[1] != 3:
                    raise ServoSetupError(f"servo id {i} is in operating mode {d[1]}: set position control mode (3)")
                if d[0] & 0x04:
                    raise ServoSetupError(f"servo id {i} uses a time-based profile (drive mode bit 2): set the "
                                          "velocity-based profile (profile velocity is a speed here)")
                lim = self.bus.read(i, 48, 8)
                if lim is None:
                    raise ServoSilent(f"servo id {i} did not answer a read of its position limits")
                hi_lim, lo_lim = int.from_bytes(lim[:4], "little"), int.from_bytes(lim[4:], "little")
                if lo_t[n] < lo_lim or hi_t[n] > hi_lim:
                    raise ServoSetupError(f"servo id {i}'s position limits [{lo_lim}, {hi_lim}] ticks would refuse "
                                          f"the gait's goals [{lo_t[n]}, {hi_t[n]}]: widen them or narrow limit_deg")

    def ticks(self, angle_rad) -> np.ndarray:
        t = self.m.angle_to_ticks(angle_rad, self.off, self.sign)
        return np.clip(t, 0, self.m.max_tick)

    def write(self, goal_ticks: np.ndarray, speed_units: np.ndarray) -> None:
        data = {i: self.m.encode_write(g, s) for i, g, s in zip(self.ids, goal_ticks.ravel(), speed_units.ravel())}
        if self.m.protocol == 2:  # dynamixel-sdk 4.1.0 does not byte-stuff instruction packets: never need it
            flat = bytes(b for i, d in data.items() for b in [i, *d])
            if b"\xff\xff\xfd" in flat:
                raise BusError("a sync write would need Protocol 2.0 byte stuffing, which dynamixel-sdk 4.1.0 "
                               "does not do; refusing to send it")
        self.bus.sync_write(self.m.addr_goal, self.m.write_size, data)

    def read(self):
        """(angle rad, velocity rad/s, load N m, ticks, error byte, monotonic time), each (robot, joint); NaN: no reply."""
        shape = self.cfg.shape
        out = [np.full(shape, np.nan) for _ in range(4)] + [np.full(shape, -1, dtype=np.int16),
                                                            np.full(shape, np.nan)]
        for n, (data, err, t) in enumerate(self.bus.read_present(self.ids, self.m)):
            idx = np.unravel_index(n, shape)
            out[5][idx] = t
            if data is None:
                continue
            pos, vel, load = self.m.decode_present(data)
            out[0][idx] = self.m.ticks_to_angle(pos, self.off[idx], self.sign[idx])
            out[1][idx] = self.sign[idx] * vel
            out[2][idx] = self.load_scale[idx] * load
            out[3][idx] = pos
            out[4][idx] = err
        return out


_FAULT_BITS_P1 = 0x04 | 0x20  # overheating, overload (the AX switches its own torque off)


def _faults(cfg: RobotConfig, err: np.ndarray) -> list[str]:
    bad = (err >= 0) & ((err & _FAULT_BITS_P1) != 0) if cfg.protocol == 1 else (err >= 0) & ((err & 0x80) != 0)
    return [f"id {cfg.id_grid[idx]} (error byte {int(err[idx])})" for idx in zip(*np.nonzero(bad))]


def _sensed_for_controller(last, angle, vel, load):
    """Hold each servo's last good reading (the controller never sees NaN)."""
    for old, new in zip(last, (angle, vel, load)):
        ok = np.isfinite(new)
        old[ok] = new[ok]
    return last


def _loop(cfg: RobotConfig, ctl: Controller, rec: _Recorder, io, clock, sleep_until, log) -> None:
    """The control ticks (shared by the run and the dry run: ``io`` is the servos or ideal servos)."""
    dt = 1.0 / cfg.rate_hz
    vmax = cfg.calibration.max_speed_rad_s
    lo, hi = cfg.lower_rad, cfg.upper_rad
    m = cfg.model
    start = np.clip(ctl.commands(np.zeros(1))[0][0], lo, hi)
    sensed = io.home(start)
    prev_goal, prev_k = start.copy(), -1
    last_ok = np.full(cfg.shape, clock())
    t0 = clock()
    k = 0
    while k < cfg.n_ticks:
        sleep_until(t0 + k * dt)
        now = clock()
        late = now - (t0 + k * dt)
        if late > dt and k > 0:  # fell behind: skip to the current tick (never send a burst)
            k_now = min(int((now - t0) / dt), cfg.n_ticks)
            rec.notes["skipped"] = rec.notes.get("skipped", 0) + (k_now - k)  # every tick ran or is counted
            if k_now == cfg.n_ticks:
                break
            k, late = k_now, now - (t0 + k_now * dt)
        t = k * dt
        angle, velocity = ctl.commands(np.array([t, t + dt]), *sensed)
        command = np.clip(angle[0], lo, hi)
        goal = np.clip(angle[1], lo, hi)
        step = vmax * (k - prev_k) * dt
        goal = np.clip(goal, prev_goal - step, prev_goal + step)
        speed = np.minimum(np.abs(goal - prev_goal) / ((k - prev_k) * dt), vmax)
        goal_ticks = io.ticks(goal)
        units = m.speed_to_register(speed)
        wall = time.time()
        io.write(goal_ticks, units)
        a, v, f, ticks, err, t_read = io.read()
        fresh = np.isfinite(a)
        last_ok[fresh] = t_read[fresh]
        rec.notes["timeouts"] = rec.notes.get("timeouts", 0) + int((~fresh).sum())
        psi = ctl.gait_phase(np.array([t]))[0]
        rec.add(k=k, wall=wall, lateness=late, command=command, goal=goal, goal_ticks=goal_ticks,
                goal_speed=m.register_to_speed(units), angle=a, velocity=v, load=f, ticks=ticks,
                sense_t=t_read - t0, error=err, phase=psi)
        silent = clock() - last_ok > cfg.max_silence_s
        if silent.any():
            ids = cfg.id_grid[silent]
            raise ServoSilent(f"servo id(s) {','.join(map(str, ids))} stopped answering "
                              f"(no reply for {cfg.max_silence_s:g} s) at t = {t:.2f} s")
        faults = _faults(cfg, err)
        if faults:
            raise ServoFault(f"hardware error at t = {t:.2f} s: " + "; ".join(faults))
        sensed = _sensed_for_controller(sensed, a, v, f)
        prev_goal, prev_k = goal, k
        k += 1


class _BusIO:
    """The real servos, for :func:`_loop`."""

    def __init__(self, cfg: RobotConfig, servos: _ServoBus, log):
        self.cfg, self.s, self.log = cfg, servos, log
        self.torque_on_sent = False

    ticks = property(lambda self: self.s.ticks)
    write = property(lambda self: self.s.write)
    read = property(lambda self: self.s.read)

    def home(self, start_rad: np.ndarray):
        """Goal := present position, torque on (confirmed), then move to ``start_rad`` at the homing speed."""
        cfg, s, m = self.cfg, self.s, self.cfg.model
        a, v, f, ticks, err, _ = s.read()
        if not np.isfinite(ticks).all():
            raise ServoSilent("servo id(s) " + ",".join(map(str, cfg.id_grid[~np.isfinite(ticks)]))
                              + " did not answer the first read")
        home_units = m.speed_to_register(np.full(cfg.shape, cfg.calibration.homing_speed_rad_s))
        s.write(ticks.astype(np.int64), home_units)
        self.torque_on_sent = True
        failed = s.bus.torque(cfg.ids, m, on=True)
        if failed:
            raise ServoSilent(f"torque enable not confirmed by id(s) {','.join(map(str, failed))}")
        goal = s.ticks(start_rad)
        s.write(goal, home_units)
        dist = float(np.nanmax(np.abs(start_rad - a)))
        deadline = time.monotonic() + dist / cfg.calibration.homing_speed_rad_s + 2.0
        tol = 3  # ticks
        while True:
            a, v, f, ticks, err, _ = s.read()
            if np.all(np.abs(ticks - goal) <= tol):
                break
            if time.monotonic() > deadline:
                off = cfg.id_grid[~(np.abs(ticks - goal) <= tol)]
                self.log(f"warning: id(s) {','.join(map(str, off))} did not reach the first pose; starting anyway")
                break
            time.sleep(0.02)
        return [np.where(np.isfinite(a), a, start_rad), np.nan_to_num(v), np.nan_to_num(f)]


class _IdealIO:
    """Servos that are exactly where they were sent (the dry run: no port)."""

    def __init__(self, cfg: RobotConfig, clock):
        self.cfg, self.clock = cfg, clock
        self.m = cfg.model
        self.pos = None
        self.vel = None

    def ticks(self, angle_rad):
        return np.clip(self.m.angle_to_ticks(angle_rad, self.cfg.offsets, self.cfg.signs), 0, self.m.max_tick)

    def home(self, start_rad):
        self.pos, self.vel = start_rad.copy(), np.zeros(self.cfg.shape)
        return [self.pos.copy(), self.vel.copy(), np.zeros(self.cfg.shape)]

    def write(self, goal_ticks, units):
        self._sent = (goal_ticks, units)

    def read(self):
        # the servo reads the set-point it was sent for now (the previous goal), moving at its speed
        pos = self.pos.copy()
        ticks, units = self._sent
        self.pos = self.m.ticks_to_angle(ticks, self.cfg.offsets, self.cfg.signs)
        shape = self.cfg.shape
        return [pos, np.zeros(shape), np.zeros(shape), np.full(shape, np.nan), np.zeros(shape, dtype=np.int16),
                np.full(shape, self.clock())]


def _describe(e: BaseException) -> str:
    if isinstance(e, Interrupted):
        return f"interrupted by {signal.Signals(e.signum).name}"
    if isinstance(e, KeyboardInterrupt):
        return "interrupted by SIGINT (KeyboardInterrupt)"
    if isinstance(e, UndulateError):
        return str(e)
    return f"{type(e).__name__}: {e}"


def run_robot(cfg: RobotConfig, out: str | Path | None = None, *, controller: Controller | None = None,
              log=print):
    """Run the gait on the servos of ``cfg`` and return the log (``xarray.Dataset``), written to ``out`` if given.

    ``controller``: the gait controller (default :func:`undulate.control.make_controller` of ``cfg.scene``,
    the object a simulation of the scene steps).  On any failure -- an exception, a signal, a silent servo,
    a lost port -- torque goes off first, then the log so far is written (``end_reason`` attr) and the
    exception is re-raised with the dataset as ``exc.dataset`` and the torque report as ``exc.torque_off``.
    """
    if cfg.port is None:
        raise ParameterError("port", "a serial device for a run (use dry_run without one)")
    ctl = make_controller(cfg.scene) if controller is None else controller
    rec = _Recorder(cfg)
    bus = DynamixelBus(cfg.port, cfg.protocol, cfg.baudrate)
    failure: BaseException | None = None
    torque_report = "never enabled"
    with _Signals() as sig:
        io = None
        try:
            bus.open()
            servos = _ServoBus(cfg, bus)
            servos.check()
            io = _BusIO(cfg, servos, log)
            _loop(cfg, ctl, rec, io, time.monotonic, _sleep_until, log)
        except BaseException as e:  # noqa: BLE001 - every exit path switches torque off, then re-raises
            failure = e
        finally:
            while True:  # a second signal can land before defer() takes effect: then simply start again
                try:
                    sig.defer()
                    break
                except Interrupted as e:
                    failure = failure or e
            if io is not None and io.torque_on_sent:
                torque_report = _torque_off(cfg, bus, log)
            bus.close()
        if failure is None and sig.pending is not None:
            failure = Interrupted(sig.pending)
        ok = failure is None
        end = "completed" if ok else _describe(failure)
        ds = None
        if rec.rows or ok:
            ds = rec.dataset(end_reason=end, torque_off=torque_report, dry=False, ok=ok)
            if out is not None:
                _write(ds, Path(out))
    if failure is not None:
        failure.dataset = ds
        failure.torque_off = torque_report
        raise failure
    return ds


def _torque_off(cfg: RobotConfig, bus: DynamixelBus, log) -> str:
    """Torque off on every servo: a broadcast, then a confirmed write each; reopen a lost port for up to 2 s."""
    m = cfg.model
    deadline = time.monotonic() + 2.0
    failed = list(cfg.ids)
    while True:
        try:
            bus.reset()
            bus.torque_off_broadcast(cfg.ids, m)
            failed = bus.torque(cfg.ids, m, on=False)
            if not failed:
                return "off on every servo (confirmed)"
            # a servo that does not answer cannot confirm: no retries through a live port
            return f"off, confirmed except id(s) {','.join(map(str, failed))} (no reply)"
        except BusLost:
            if time.monotonic() > deadline:
                break
            time.sleep(0.2)
            try:
                bus.reopen()
            except BusError:
                pass
    msg = (f"NOT confirmed on id(s) {','.join(map(str, failed))}: the port is gone ({cfg.port}); the servos "
           "hold their last goal until their power is removed")
    log(f"warning: torque off {msg}")
    return msg


def _sleep_until(t_target: float) -> None:
    while True:
        left = t_target - time.monotonic()
        if left <= 0:
            return
        time.sleep(left - 0.0005 if left > 0.001 else 0)  # the last half millisecond spins (sleep(0) yields)


def _write(ds, out: Path) -> None:
    from .._io import write_netcdf

    write_netcdf(ds, out, compress=False)


def dry_run(cfg: RobotConfig, out: str | Path | None = None, *, controller: Controller | None = None):
    """The commanded trajectory without a port: ideal servos (exactly at each set-point), no waiting.

    For the open-loop gait, ``joint_command``, ``goal_position`` and ``goal_speed`` are those a real run sends
    (unless a servo falls behind and the slew limit acts).  Closed-loop controllers see perfect tracking and
    zero load, i.e. their free gait.
    """
    ctl = make_controller(cfg.scene) if controller is None else controller
    rec = _Recorder(cfg)
    clock = _VirtualClock()
    _loop(cfg, ctl, rec, _IdealIO(cfg, clock), clock, clock.sleep_until, print)
    ds = rec.dataset(end_reason="dry run (no port opened)", torque_off="no port opened", dry=True, ok=True)
    if out is not None:
        _write(ds, Path(out))
    return ds


class _VirtualClock:
    def __init__(self):
        self.t = 0.0

    def __call__(self) -> float:
        return self.t

    def sleep_until(self, t: float) -> None:
        self.t = max(self.t, t)


def schedule_text(cfg: RobotConfig, ds=None, rows: int = 11) -> str:
    """What a run will do, for ``--dry-run``: the bus, every servo's mapping, the tick schedule."""
    m, sc = cfg.model, cfg.scene
    g = sc.gait
    lines = [
        f"bus: protocol {cfg.protocol}, {cfg.baudrate} bit/s, {m.name} ({m.resolution_ticks} ticks over "
        f"{m.range_deg:g} deg, centre {m.centre_ticks}), port {cfg.port or '(none: dry run)'}",
        f"gait: {sc.controller.kind}, beta = {math.degrees(g.amplitude_rad):g} deg, f = {g.frequency_hz:g} Hz, "
        f"xi = {g.waves_per_body:g}, {sc.geometry.n_links} links; peak joint speed "
        f"{math.degrees(2 * math.pi * g.frequency_hz * g.amplitude_rad):.0f} deg/s (max commanded "
        f"{math.degrees(cfg.calibration.max_speed_rad_s):g} deg/s)",
        f"schedule: {cfg.n_ticks} ticks at {cfg.rate_hz:g} Hz over {cfg.duration_s:g} s; one sync write of "
        f"{len(cfg.ids)} goals per tick, then {'one read per servo' if cfg.protocol == 1 else 'one sync read'}",
        f"calibration: {cfg.calibration.source}",
    ]
    for (r, j), sid in np.ndenumerate(cfg.id_grid):
        jc = cfg.calibration.joint(int(sid))
        lines.append(f"  robot {r} (phi = {math.degrees(sc.phases_rad[r]):g} deg) joint {j}: id {sid}, offset "
                     f"{jc.offset_ticks:+d} ticks, sign {jc.sign:+d}, limits [{math.degrees(jc.lower_rad):g}, "
                     f"{math.degrees(jc.upper_rad):g}] deg")
    for w in cfg.clipped_joints():
        lines.append(f"warning: {w}")
    if ds is not None:
        ids = " ".join(f"{i:>5d}" for i in cfg.ids)
        lines.append(f"goal positions sent (ticks) at gait time t, for t + {1 / cfg.rate_hz:g} s:")
        lines.append(f"  {'t (s)':>7s} {ids}")
        step = max(1, int(round(g.period_s * cfg.rate_hz / (rows - 1))))
        for i in range(0, min(ds.sizes["time"], step * rows), step):
            row = " ".join(f"{int(v):>5d}" for v in ds["goal_position"].values[i].ravel())
            lines.append(f"  {float(ds['time'].values[i]):7.2f} {row}")
    return "\n".join(lines)


def ping(port: str, protocol: int, baudrate: int = 1_000_000, ids=None) -> dict[int, str]:
    """The servos answering on ``port``: ``{id: model name (or 'model N')}``."""
    bus = DynamixelBus(port, protocol, baudrate)
    bus.open()
    try:
        found = bus.scan(ids)
    finally:
        bus.close()
    names = {m.model_number: m.name for m in SERVO_MODELS.values() if m.protocol == protocol}
    return {i: names.get(n, f"model {n}") for i, n in found.items()}
