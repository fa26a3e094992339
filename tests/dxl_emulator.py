"""An emulated Dynamixel servo bus on a pseudo-terminal (test code).

:class:`ServoBus` opens a pty, hands its slave device path (``bus.port``) to
whoever wants to talk to servos (``dynamixel-sdk`` opens it like a USB2Dynamixel
adapter) and answers on the master side from a thread, byte for byte as the
servos' firmware does:

* **Protocol 1.0** (AX-12A, AX-18A): ``FF FF ID LEN INST PARAMS CHK`` with
  ``CHK = ~(ID + LEN + INST + sum(PARAMS)) & 0xFF``; PING, READ, WRITE,
  SYNC_WRITE; status ``FF FF ID LEN ERR PARAMS CHK`` with the error bits
  (angle limit 2, range 8, checksum 16, instruction 64).
* **Protocol 2.0** (XL430-W250): ``FF FF FD 00 ID LEN_L LEN_H INST PARAMS
  CRC_L CRC_H`` with the CRC-16 of the packet (polynomial 0x8005) and byte
  stuffing (``FF FF FD`` -> ``FF FF FD FD`` from the instruction on); PING
  (also broadcast), READ, WRITE, SYNC_READ, SYNC_WRITE; status instruction
  0x55 with error numbers (instruction 2, CRC 3, data limit 6, access 7).

Each servo keeps a control table (the ROBOTIS addresses and defaults) with
a torque-enable register; its present position follows the goal with
first-order dynamics (time constant ``tau_s``) at most at the moving speed /
profile velocity (no-load speed when that register is 0), advanced in
closed form to the wall-clock time of each packet.  Present load is the
servo's output torque model ``clip(error / load_full_ticks, -1, 1)`` in the
protocol's encoding (AX: sign-magnitude with bit 10 for CW).  Answers are
delayed by the wire time at the bus baud rate plus the Return Delay Time
register, so timings measured against the emulator include the bus; a host
whose pty speed differs from the servos' baud rate is not understood.

This is an independent implementation of the protocol (it shares no code
with ``undulate.robot``); ``tests/test_robot_emulator.py`` cross-checks its
encoding against ``dynamixel-sdk``'s own packet handlers.

Faults for tests: :meth:`ServoBus.drop` (a servo misses a few packets),
:meth:`ServoBus.silence` (a servo stops answering), :meth:`ServoBus.unplug`
(the adapter is pulled out: the pty closes and ``link`` disappears) and :meth:`ServoBus.glitch` (the
adapter re-enumerates: a new pty behind the same ``link``, as udev's
``/dev/serial/by-id`` links do; the servos keep their state).
"""

from __future__ import annotations

import math
import os
import select
import termios
import threading
import time
import tty
from dataclasses import dataclass, field

BROADCAST = 0xFE

# --- checksums -------------------------------------------------------------------------------


def p1_checksum(body: bytes) -> int:
    """Protocol 1.0 checksum of ID..last parameter."""
    return (~sum(body)) & 0xFF


def crc16(data: bytes) -> int:
    """Protocol 2.0 CRC-16 (polynomial 0x8005, initial 0, not reflected), bit by bit."""
    crc = 0
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def stuff(region: bytes) -> bytes:
    """Protocol 2.0 byte stuffing: an FD after every FF FF FD."""
    out = bytearray()
    for b in region:
        out.append(b)
        if len(out) >= 3 and out[-3:] == b"\xff\xff\xfd":
            out.append(0xFD)
    return bytes(out)


def unstuff(region: bytes) -> bytes:
    """Undo :func:`stuff`: drop the FD that follows FF FF FD."""
    out = bytearray()
    i = 0
    while i < len(region):
        out.append(region[i])
        if len(out) >= 3 and out[-3:] == b"\xff\xff\xfd" and i + 1 < len(region) and region[i + 1] == 0xFD:
            i += 1  # the stuffed byte
        i += 1
    return bytes(out)


def p1_packet(ident: int, first: int, params: bytes = b"") -> bytes:
    """A Protocol 1.0 packet (instruction or status: ``first`` is INST or ERR)."""
    body = bytes([ident, len(params) + 2, first]) + bytes(params)
    return b"\xff\xff" + body + bytes([p1_checksum(body)])


def p2_packet(ident: int, inst: int, params: bytes = b"", error: int | None = None) -> bytes:
    """A Protocol 2.0 packet: instruction ``inst``, or a status packet when ``error`` is given."""
    region = bytes([inst]) + (bytes([error]) if error is not None else b"") + bytes(params)
    region = stuff(region)
    n = len(region) + 2
    pkt = b"\xff\xff\xfd\x00" + bytes([ident, n & 0xFF, n >> 8]) + region
    c = crc16(pkt)
    return pkt + bytes([c & 0xFF, c >> 8])


# --- servo models ----------------------------------------------------------------------------


@dataclass
class Model:
    name: str
    protocol: int
    number: int
    size: int  # control table bytes
    resolution: int  # ticks per full range
    speed_unit_rpm: float
    no_load_rpm: float
    defaults: dict  # address -> (size, value)
    read_only: tuple  # (start, stop) ranges
    eeprom_end: int  # addresses below are EEPROM (P2: not writable while torque is on)
    torque: int
    goal: int
    speed: int  # moving speed / profile velocity
    speed_size: int
    present_position: int
    present_speed: int
    present_load: int
    position_size: int
    moving: int


AX12A = Model(
    "AX-12A", 1, 12, 50, 1024, 0.111, 59.0,
    defaults={0: (2, 12), 2: (1, 24), 3: (1, 1), 4: (1, 1), 5: (1, 250), 6: (2, 0), 8: (2, 1023), 11: (1, 70),
              12: (1, 60), 13: (1, 140), 14: (2, 1023), 16: (1, 2), 17: (1, 36), 18: (1, 36), 26: (1, 1),
              27: (1, 1), 28: (1, 32), 29: (1, 32), 30: (2, 512), 34: (2, 1023), 36: (2, 512), 42: (1, 120),
              43: (1, 30), 48: (2, 32)},
    read_only=((0, 3), (36, 47)), eeprom_end=19, torque=24, goal=30, speed=32, speed_size=2,
    present_position=36, present_speed=38, present_load=40, position_size=2, moving=46,
)
AX18A = Model(**{**AX12A.__dict__, "name": "AX-18A", "number": 18, "no_load_rpm": 97.0,
                 "defaults": {**AX12A.defaults, 0: (2, 18)}})
XL430 = Model(
    "XL430-W250", 2, 1060, 148, 4096, 0.229, 57.0,
    defaults={0: (2, 1060), 6: (1, 45), 7: (1, 1), 8: (1, 3), 9: (1, 250), 11: (1, 3), 13: (1, 2), 24: (4, 10),
              31: (1, 72), 32: (2, 140), 34: (2, 60), 36: (2, 885), 44: (4, 265), 48: (4, 4095), 52: (4, 0),
              63: (1, 52), 68: (1, 2), 76: (2, 1000), 78: (2, 100), 80: (2, 4000), 84: (2, 640),
              116: (4, 2048), 132: (4, 2048), 144: (2, 120), 146: (1, 30)},
    read_only=((0, 7), (69, 71), (120, 148)), eeprom_end=64, torque=64, goal=116, speed=112, speed_size=4,
    present_position=132, present_speed=128, present_load=126, position_size=4, moving=122,
)
MODELS = {m.name: m for m in (AX12A, AX18A, XL430)}


@dataclass
class Servo:
    ident: int
    model: Model
    table: bytearray = field(default_factory=bytearray)
    pos: float = 0.0  # ticks
    vel: float = 0.0  # ticks/s
    t: float = 0.0
    silent: bool = False
    drops: int = 0  # packets addressed to this servo that it misses
    reported: list = field(default_factory=list)  # (wall time, present position ticks) in each reply to a read
    goals: list = field(default_factory=list)  # (wall time, goal ticks, speed register)
    torque_log: list = field(default_factory=list)  # (wall time, value)

    def __post_init__(self):
        m = self.model
        self.table = bytearray(m.size)
        for addr, (n, v) in m.defaults.items():
            self.put(addr, n, v)
        self.put(7 if m.protocol == 2 else 3, 1, self.ident)
        self.pos = float(self.get(m.present_position, m.position_size))
        self.t = time.time()

    def get(self, addr: int, n: int, signed: bool = False) -> int:
        return int.from_bytes(self.table[addr:addr + n], "little", signed=signed)

    def put(self, addr: int, n: int, value: int) -> None:
        self.table[addr:addr + n] = int(value).to_bytes(n, "little", signed=value < 0)

    # first-order dynamics with a speed limit, in closed form
    tau_s = 0.02
    load_full_ticks = 40.0

    def advance(self, now: float) -> None:
        m = self.model
        dt, self.t = max(0.0, now - self.t), now
        if self.get(m.torque, 1) == 0:
            self.vel = 0.0
        else:
            speed_reg = self.get(m.speed, m.speed_size)
            rpm = m.no_load_rpm if speed_reg == 0 else min(speed_reg * m.speed_unit_rpm, m.no_load_rpm)
            ticks_per_rev = m.resolution * (360.0 / 300.0 if m.protocol == 1 else 1.0)
            vmax = rpm / 60.0 * ticks_per_rev
            goal = float(self.get(m.goal, m.position_size, signed=m.protocol == 2))
            e = goal - self.pos
            s, a = math.copysign(1.0, e), abs(e)
            edge = vmax * self.tau_s
            if a > edge:
                t_sat = (a - edge) / vmax
                if dt <= t_sat:
                    a -= vmax * dt
                    dt = 0.0
                else:
                    a, dt = edge, dt - t_sat
            a *= math.exp(-dt / self.tau_s)
            self.pos = goal - s * a
            self.vel = s * min(a / self.tau_s, vmax)
        self._sync_present()

    def _sync_present(self) -> None:
        m = self.model
        ticks = int(round(self.pos))
        speed = int(round(abs(self.vel) / (m.resolution * (360.0 / 300.0 if m.protocol == 1 else 1.0))
                          * 60.0 / m.speed_unit_rpm))
        goal = self.get(m.goal, m.position_size, signed=m.protocol == 2)
        torque_on = self.get(m.torque, 1) == 1
        load = max(-1.0, min(1.0, (goal - self.pos) / self.load_full_ticks)) if torque_on else 0.0
        moving = int(torque_on and abs(goal - self.pos) > 1.0)
        if m.protocol == 1:
            self.put(m.present_position, 2, max(0, min(1023, ticks)))
            self.put(m.present_speed, 2, min(speed, 1023) | (1024 if self.vel < 0 else 0))  # bit 10: CW
            mag = min(int(round(abs(load) * 1000)), 1023)
            self.put(m.present_load, 2, mag | (1024 if load < 0 else 0))  # sign-magnitude, bit 10: CW
        else:
            self.put(m.present_position, 4, ticks)
            self.put(m.present_speed, 4, int(math.copysign(speed, self.vel)))
            self.put(m.present_load, 2, int(round(load * 1000)))
        self.put(m.moving, 1, moving)


# --- the bus ---------------------------------------------------------------------------------


class ServoBus:
    """Emulated servos of one protocol on a pty (see the module docstring).

    ``servos``: ``{id: model name}``; ``baudrate``: the servos' bus speed, bit/s.
    """

    def __init__(self, protocol: int, servos: dict[int, str], baudrate: int = 1_000_000,
                 return_delay_us: float | None = None, link: str | None = None):
        self.protocol = protocol
        self.baudrate = baudrate
        self.servos = {}
        for i, name in servos.items():
            m = MODELS[name]
            if m.protocol != protocol:
                raise ValueError(f"{name} speaks protocol {m.protocol}")
            s = Servo(i, m)
            if return_delay_us is not None:
                s.put(5 if protocol == 1 else 9, 1, int(return_delay_us / 2))
            self.servos[i] = s
        self.packets: list[tuple[float, int, int, bytes]] = []  # (time, id, instruction, params)
        self.bad_packets = 0
        self.bytes_in = 0
        self.lock = threading.Lock()
        self.link = link
        self._start()

    def _start(self) -> None:
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self._set_speed(self.baudrate)
        self.device = os.ttyname(self._slave)
        if self.link is not None:
            tmp = self.link + ".new"
            if os.path.lexists(tmp):
                os.unlink(tmp)
            os.symlink(self.device, tmp)
            os.replace(tmp, self.link)
        self.port = self.link or self.device
        self._buf = bytearray()
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="dxl-emulator", daemon=True)
        self._thread.start()

    # -- control from tests
    def silence(self, ident: int, silent: bool = True) -> None:
        """Servo ``ident`` stops (or resumes) answering and obeying: a cut cable."""
        with self.lock:
            self.servos[ident].silent = silent

    def drop(self, ident: int, n: int) -> None:
        """Servo ``ident`` misses its next ``n`` requests for a reply (an isolated time-out each)."""
        with self.lock:
            self.servos[ident].drops += n

    def unplug(self) -> None:
        """The adapter is pulled out for good: the pty closes and ``link`` disappears."""
        self.close()
        if self.link is not None and os.path.lexists(self.link):
            os.unlink(self.link)

    def glitch(self, down_s: float = 0.3) -> None:
        """The adapter drops off the bus for ``down_s`` and comes back as a new device behind ``link``."""
        self.close()
        if self.link is not None and os.path.lexists(self.link):
            os.unlink(self.link)
        time.sleep(down_s)
        self._start()

    def close(self) -> None:
        """The bus disappears: close the pty (the host sees an I/O error)."""
        if self._closed.is_set():
            return
        self._closed.set()
        self._thread.join(timeout=2)
        for fd in (self.master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass

    def torque(self, ident: int) -> int:
        with self.lock:
            s = self.servos[ident]
            return s.get(s.model.torque, 1)

    def register(self, ident: int, addr: int, n: int, signed: bool = False) -> int:
        with self.lock:
            s = self.servos[ident]
            s.advance(time.time())
            return s.get(addr, n, signed)

    def position(self, ident: int) -> float:
        """Present position, ticks (float, not rounded)."""
        with self.lock:
            s = self.servos[ident]
            s.advance(time.time())
            return s.pos

    def set_position(self, ident: int, ticks: float) -> None:
        """Move a servo's horn by hand (torque off) or teleport it."""
        with self.lock:
            s = self.servos[ident]
            s.pos = float(ticks)
            s._sync_present()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- the serving thread
    def _set_speed(self, baud: int) -> None:
        attrs = termios.tcgetattr(self._slave)
        speed = getattr(termios, f"B{baud}")
        attrs[4] = attrs[5] = speed
        termios.tcsetattr(self._slave, termios.TCSANOW, attrs)

    def _host_speed_ok(self) -> bool:
        try:
            attrs = termios.tcgetattr(self._slave)
        except termios.error:
            return True
        return attrs[5] == getattr(termios, f"B{self.baudrate}")

    def _serve(self) -> None:
        while not self._closed.is_set():
            try:
                r, _, _ = select.select([self.master], [], [], 0.05)
                if not r:
                    continue
                data = os.read(self.master, 4096)
            except OSError:
                return
            if not data:
                continue
            t_rx = time.time()
            self.bytes_in += len(data)
            if not self._host_speed_ok():  # wrong baud rate: the servos see noise
                with self.lock:
                    self.bad_packets += 1
                continue
            self._buf.extend(data)
            while True:
                pkt = self._take_packet()
                if pkt is None:
                    break
                try:
                    self._handle(pkt, t_rx)
                except OSError:
                    return

    def _take_packet(self):
        """Cut one complete instruction packet off the buffer (resynchronising on the header)."""
        buf = self._buf
        if self.protocol == 1:
            while len(buf) >= 2 and buf[:2] != b"\xff\xff":
                del buf[0]
            if len(buf) < 4:
                return None
            n = buf[3]
            total = n + 4
            if len(buf) < total:
                return None
            pkt = bytes(buf[:total])
            del buf[:total]
            return pkt
        while len(buf) >= 4 and not (buf[:3] == b"\xff\xff\xfd" and buf[3] == 0):
            del buf[0]
        if len(buf) < 7:
            return None
        n = buf[5] | buf[6] << 8
        total = n + 7
        if len(buf) < total:
            return None
        pkt = bytes(buf[:total])
        del buf[:total]
        return pkt

    def _wire_s(self, nbytes: int) -> float:
        return nbytes * 10.0 / self.baudrate

    def _reply(self, servo: Servo, pkt: bytes, t_ready: float) -> float:
        """Send a status packet no earlier than ``t_ready`` plus the return delay; returns when it ends."""
        t_send = t_ready + servo.get(5 if self.protocol == 1 else 9, 1) * 2e-6
        now = time.time()
        if t_send > now:
            time.sleep(t_send - now)
        os.write(self.master, pkt)
        return max(t_send, now) + self._wire_s(len(pkt))

    # -- instruction handling
    def _handle(self, pkt: bytes, t_rx: float) -> None:
        t_end = t_rx + self._wire_s(len(pkt))  # the instruction's last byte arrives
        if self.protocol == 1:
            ident, inst, params = pkt[2], pkt[4], pkt[5:-1]
            ok = p1_checksum(pkt[2:-1]) == pkt[-1]
        else:
            ident, inst = pkt[4], pkt[7]
            ok = crc16(pkt[:-2]) == (pkt[-2] | pkt[-1] << 8)
            params = unstuff(pkt[7:-2])[1:]
        with self.lock:
            self.packets.append((t_rx, ident, inst, bytes(params)))
            if not ok:
                self.bad_packets += 1
            for s in self.servos.values():
                s.advance(t_rx)
            replies = self._execute(ident, inst, bytes(params), ok, t_rx)
        for servo, reply in replies:
            t_end = self._reply(servo, reply, t_end)

    def _status(self, servo: Servo, error: int, params: bytes = b"") -> tuple[Servo, bytes]:
        if self.protocol == 1:
            return servo, p1_packet(servo.ident, error, params)
        return servo, p2_packet(servo.ident, 0x55, params, error=error)

    def _live(self, ident: int):
        s = self.servos.get(ident)
        return None if s is None or s.silent else s

    def _answers(self, s: Servo) -> bool:
        """Whether ``s`` answers this request (:meth:`drop` makes it miss some)."""
        if s.drops:
            s.drops -= 1
            return False
        return True

    def _execute(self, ident: int, inst: int, params: bytes, ok: bool, t: float):
        p1 = self.protocol == 1
        if ident == BROADCAST:
            if not ok:
                return []
            if inst == 0x83:  # SYNC_WRITE
                if p1:
                    addr, n, rest = params[0], params[1], params[2:]
                else:
                    addr, n, rest = params[0] | params[1] << 8, params[2] | params[3] << 8, params[4:]
                for k in range(0, len(rest) - n + 1, n + 1):
                    s = self._live(rest[k])
                    if s is not None:
                        self._write(s, addr, rest[k + 1:k + 1 + n], t)
                return []
            if inst == 0x82 and not p1:  # SYNC_READ: answers in the order asked
                addr, n = params[0] | params[1] << 8, params[2] | params[3] << 8
                out = []
                for i in params[4:]:
                    s = self._live(i)
                    if s is not None and self._answers(s):
                        err, data = self._read(s, addr, n)
                        out.append(self._status(s, err, data))
                return out
            if inst == 0x01 and not p1:  # broadcast PING
                return [self._status(s, 0, self._ping_data(s)) for i, s in sorted(self.servos.items())
                        if not s.silent]
            return []
        s = self._live(ident)
        if s is None or not self._answers(s):
            return []
        if not ok:
            return [self._status(s, 16 if p1 else 3)]
        if inst == 0x01:  # PING
            return [self._status(s, 0, b"" if p1 else self._ping_data(s))]
        if inst == 0x02:  # READ
            addr, n = (params[0], params[1]) if p1 else (params[0] | params[1] << 8, params[2] | params[3] << 8)
            err, data = self._read(s, addr, n)
            return [self._status(s, err, data)]
        if inst == 0x03:  # WRITE
            addr, data = (params[0], params[1:]) if p1 else (params[0] | params[1] << 8, params[2:])
            return [self._status(s, self._write(s, addr, data, t))]
        return [self._status(s, 64 if p1 else 2)]  # instruction error

    def _ping_data(self, s: Servo) -> bytes:
        return bytes([s.model.number & 0xFF, s.model.number >> 8, s.get(6, 1)])

    def _read(self, s: Servo, addr: int, n: int) -> tuple[int, bytes]:
        if addr + n > s.model.size or n == 0:
            return (8 if self.protocol == 1 else 7), b""
        m = s.model
        if addr <= m.present_position and addr + n >= m.present_position + m.position_size:
            s.reported.append((s.t, s.get(m.present_position, m.position_size, signed=m.protocol == 2)))
        return 0, bytes(s.table[addr:addr + n])

    def _write(self, s: Servo, addr: int, data: bytes, t: float) -> int:
        m = s.model
        p1 = self.protocol == 1
        end = addr + len(data)
        if end > m.size or not data:
            return 8 if p1 else 7
        for a, b in m.read_only:
            if addr < b and end > a:
                return 8 if p1 else 7
        torque_on = s.get(m.torque, 1) == 1
        if not p1 and addr < m.eeprom_end and torque_on:
            return 7  # access error: EEPROM is locked while torque is on
        new = bytearray(s.table)
        new[addr:end] = data
        goal = int.from_bytes(new[m.goal:m.goal + m.position_size], "little", signed=not p1)
        if p1:
            lo, hi = s.get(6, 2), s.get(8, 2)
            if addr <= m.goal + 1 and end > m.goal and not (lo <= goal <= hi):
                return 2  # angle limit error: the goal is not taken
        else:
            lo, hi = s.get(52, 4), s.get(48, 4)
            if addr <= m.goal + 3 and end > m.goal and not (lo <= goal <= hi):
                return 6  # data limit error
        if new[m.torque] > 1:
            return 8 if p1 else 6
        s.table[:] = new
        if addr <= m.goal < end:
            s.goals.append((t, goal, s.get(m.speed, m.speed_size)))
        if addr <= m.torque < end:
            s.torque_log.append((t, s.table[m.torque]))
            if s.table[m.torque] == 0:
                s.vel = 0.0
        s._sync_present()
        return 0


if __name__ == "__main__":  # pragma: no cover - a bus for manual runs: python tests/dxl_emulator.py 1 1,2,3,4
    import sys

    proto = int(sys.argv[1])
    ids = [int(i) for i in sys.argv[2].split(",")]
    bus = ServoBus(proto, {i: "AX-12A" if proto == 1 else "XL430-W250" for i in ids})
    print(bus.port, flush=True)
    try:
        while True:
            time.sleep(1)
    except KeyboardInterrupt:
        bus.close()
