"""One Dynamixel bus through ROBOTIS's ``dynamixel-sdk``: open, ping, read, write, torque.

Every call goes through :meth:`DynamixelBus._io`, which turns a serial-port
failure (``serial.SerialException`` / ``OSError``: the adapter unplugged or
the device gone) into :class:`BusLost` and releases the SDK's port lock, so
that an exception or a signal arriving inside an SDK call never leaves the
port marked busy for the torque-off that follows.

Reads: Protocol 1.0 has no sync read (and ``dynamixel-sdk`` 4.1.0's
``GroupBulkRead`` fails on it; the AX has no bulk read), so each servo is read
with one READ of its whole present-state block.  Protocol 2.0 sends one
SYNC_READ and takes each servo's status packet with the packet handler's
``readRx`` -- the calls ``GroupSyncRead`` makes, kept per servo; a servo whose
packet did not come is then read on its own (a missing packet makes
``readRx`` skip the ones after it), so one servo's time-out costs only its
own reading.

Protocol 2.0 byte stuffing: ``dynamixel-sdk`` 4.1.0 does not stuff
instruction packets (its ``addStuffing`` result is dropped when it had to
stuff); the values this driver sends can never contain ``FF FF FD``, and the
run refuses a write that would (tests/test_robot.py pins both).
"""

from __future__ import annotations

import time

from ..errors import UndulateError
from .servos import ServoModel

__all__ = ["BusError", "BusLost", "ServoSilent", "ServoFault", "ServoSetupError", "DynamixelBus", "sdk"]


class BusError(UndulateError, RuntimeError):
    """Something went wrong on the servo bus."""


class BusLost(BusError):
    """The serial port failed (adapter unplugged, device gone)."""


class ServoSilent(BusError):
    """Servos stopped answering."""


class ServoFault(BusError):
    """A servo reported a hardware error (overload, overheating)."""


class ServoSetupError(BusError):
    """The servos found do not match the run (missing id, other model, wrong mode)."""


def sdk():
    """``dynamixel_sdk``, or a one-line error saying how to install it."""
    try:
        import dynamixel_sdk
    except ImportError:  # pragma: no cover - the robot extra is installed in tests
        raise BusError("the robot driver needs dynamixel-sdk: pip install 'undulate[robot]'") from None
    return dynamixel_sdk


class DynamixelBus:
    """A serial port and a packet handler of one protocol (1 or 2)."""

    def __init__(self, port_name: str, protocol: int, baudrate: int):
        self.sdk = sdk()
        self.port_name = port_name
        self.protocol = int(protocol)
        self.baudrate = int(baudrate)
        self.port = self.sdk.PortHandler(port_name)
        self.ph = self.sdk.PacketHandler(float(protocol))
        self.is_open = False

    # --- port ----------------------------------------------------------------------------------
    def _io(self, fn, *args, opening: bool = False):
        import termios

        import serial

        if not (self.is_open or opening):
            raise BusLost(f"serial port {self.port_name} is not open")
        try:
            return fn(*args)
        except (serial.SerialException, OSError, termios.error) as e:
            self.port.is_using = False
            raise BusLost(f"serial port {self.port_name} failed: {e}") from None
        except BaseException:
            self.port.is_using = False  # interrupted inside an SDK call: release its port lock
            raise

    def open(self) -> None:
        ok = self._io(self.port.openPort, opening=True) and self._io(self.port.setBaudRate, self.baudrate, opening=True)
        if not ok:
            raise BusLost(f"could not open {self.port_name} at {self.baudrate} bit/s")
        self.is_open = True

    def close(self) -> None:
        if self.is_open:
            try:
                self.port.closePort()
            except Exception:
                pass
        self.is_open = False

    def reopen(self) -> None:
        """Close and open the port again by name (an adapter that re-enumerated)."""
        self.close()
        self.port = self.sdk.PortHandler(self.port_name)
        self.open()

    def reset(self) -> None:
        """Release the SDK's port lock and drop stale bytes (before a torque-off)."""
        self.port.is_using = False
        if self.is_open:
            self._io(self.port.clearPort)

    # --- transactions --------------------------------------------------------------------------
    def ping(self, servo_id: int) -> int | None:
        """Model number of ``servo_id``, or None when it does not answer."""
        model, result, _ = self._io(self.ph.ping, self.port, servo_id)
        return int(model) if result == self.sdk.COMM_SUCCESS else None

    def scan(self, ids=None) -> dict[int, int]:
        """``{id: model number}`` of the servos that answer (Protocol 2 without ids: broadcast ping)."""
        if ids is None and self.protocol == 2:
            found, result = self._io(self.ph.broadcastPing, self.port)
            return {int(i): int(v[0]) for i, v in sorted(found.items())} if result == self.sdk.COMM_SUCCESS else {}
        ids = range(0, 253 if self.protocol == 2 else 254) if ids is None else ids
        out = {}
        for i in ids:
            m = self.ping(i)
            if m is not None:
                out[int(i)] = m
        return out

    def read(self, servo_id: int, addr: int, n: int) -> bytes | None:
        data, result, _ = self._io(self.ph.readTxRx, self.port, servo_id, addr, n)
        return bytes(data) if result == self.sdk.COMM_SUCCESS and len(data) == n else None

    def write1(self, servo_id: int, addr: int, value: int) -> bool:
        result, error = self._io(self.ph.write1ByteTxRx, self.port, servo_id, addr, value)
        return result == self.sdk.COMM_SUCCESS and error == 0

    def sync_write(self, addr: int, n: int, data: dict[int, list[int]]) -> None:
        """One SYNC_WRITE (broadcast, no reply) of ``n`` bytes per servo."""
        g = self.sdk.GroupSyncWrite(self.port, self.ph, addr, n)
        for i, d in data.items():
            g.addParam(int(i), list(d))
        result = self._io(g.txPacket)
        if result != self.sdk.COMM_SUCCESS:
            raise BusLost(f"sync write failed on {self.port_name}: {self.ph.getTxRxResult(result)}")

    def read_present(self, ids, model: ServoModel) -> list[tuple[bytes | None, int, float]]:
        """Each servo's present-state block: ``(data or None, error byte, time.monotonic() of the reading)``."""
        n, addr = model.present_size, model.addr_present
        out = []
        if self.protocol == 1:
            for i in ids:
                t = time.monotonic()
                data, result, error = self._io(self.ph.readTxRx, self.port, int(i), addr, n)
                ok = result == self.sdk.COMM_SUCCESS and len(data) == n
                out.append((bytes(data) if ok else None, int(error) if ok else -1, (t + time.monotonic()) / 2))
            return out
        t = time.monotonic()
        result = self._io(self.ph.syncReadTx, self.port, addr, n, [int(i) for i in ids], len(ids), False)
        if result != self.sdk.COMM_SUCCESS:
            raise BusLost(f"sync read failed on {self.port_name}: {self.ph.getTxRxResult(result)}")
        for i in ids:
            data, result, error = self._io(self.ph.readRx, self.port, int(i), n)
            ok = result == self.sdk.COMM_SUCCESS and len(data) == n
            out.append((bytes(data) if ok else None, int(error) if ok else -1, (t + time.monotonic()) / 2))
        self.port.is_using = False
        # a missing status packet also costs the ones after it (readRx skips them while it waits):
        # ask each servo that did not answer on its own, so only a servo that is really silent reads NaN
        for k, i in enumerate(ids):
            if out[k][0] is None:
                t = time.monotonic()
                data, result, error = self._io(self.ph.readTxRx, self.port, int(i), addr, n)
                ok = result == self.sdk.COMM_SUCCESS and len(data) == n
                if ok:
                    out[k] = (bytes(data), int(error), (t + time.monotonic()) / 2)
        return out

    def torque(self, ids, model: ServoModel, on: bool, tries: int = 3) -> list[int]:
        """Set torque enable on every servo, confirmed by its status packet; returns the ids not confirmed."""
        failed = []
        for i in ids:
            for _ in range(tries):
                if self.write1(int(i), model.addr_torque_enable, 1 if on else 0):
                    break
            else:
                failed.append(int(i))
        return failed

    def torque_off_broadcast(self, ids, model: ServoModel) -> None:
        """Torque off on every servo at once: one SYNC_WRITE, no reply."""
        self.sync_write(model.addr_torque_enable, 1, {int(i): [0] for i in ids})
