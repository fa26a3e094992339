"""Control-loop timing of ``undulate robot run`` against the emulated servo bus (measured, never asserted).

    python benchmarks/bench_robot_loop.py [--duration 20] [--rate 50]

4 robots x 2 joints (8 servos) at 1 Mbit/s, Protocol 1.0 (AX-12A: one read
per servo) and 2.0 (XL430-W250: one sync read), the servos' default Return
Delay Time (250 -> 500 us) and 0.  The emulator (tests/dxl_emulator.py) runs
in this process; the driver is the CLI in a child process, as it would run
against real servos.  The emulator delays each status packet by its wire
time at the baud rate plus the return delay, so bus time is included; what a
USB adapter adds (the FTDI latency timer) is not: see docs/robots.md.

Reported per configuration: achieved tick rate, tick lateness (start of the
tick minus its schedule: the jitter) rms / 99th percentile / max, skipped
ticks, read time-outs, and the bus time per tick (from the tick's start to
its last reading).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import xarray as xr

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from dxl_emulator import ServoBus  # noqa: E402

IDS = (1, 2, 3, 4, 5, 6, 7, 8)


def one(protocol: int, delay_us: float, duration: float, rate: float) -> dict:
    model = "AX-12A" if protocol == 1 else "XL430-W250"
    with ServoBus(protocol, {i: model for i in IDS}, return_delay_us=delay_us) as bus, \
            tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run.nc"
        cmd = [sys.executable, "-m", "undulate.cli", "robot", "run", "--port", bus.port, "--protocol", str(protocol),
               "--ids", ",".join(map(str, IDS)), "--phases", "0,90,180,270", "--duration", str(duration),
               "--control-rate", str(rate), "--out", str(out)]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(r.stderr)
        ds = xr.load_dataset(out, engine="h5netcdf")
    lat = ds["tick_lateness"].values
    t = ds["time"].values
    bus_time = np.nanmax(ds["sense_time"].values.reshape(len(t), -1), axis=1) - t  # to the tick's last reading
    return {
        "protocol": protocol, "return_delay_us": delay_us, "ticks": len(t),
        "rate_Hz": ds.attrs["control_rate_achieved"], "late_rms_ms": 1e3 * float(np.sqrt(np.mean(lat ** 2))),
        "late_p99_ms": 1e3 * float(np.percentile(lat, 99)), "late_max_ms": 1e3 * float(lat.max()),
        "skipped": ds.attrs["ticks_skipped"], "timeouts": ds.attrs["read_timeouts"],
        "bus_ms_median": 1e3 * float(np.median(bus_time)), "bus_ms_max": 1e3 * float(np.max(bus_time)),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--rate", type=float, default=50.0)
    a = ap.parse_args()
    print(f"{'protocol':>8} {'delay us':>8} {'ticks':>6} {'rate Hz':>8} {'late rms ms':>11} {'p99 ms':>7} "
          f"{'max ms':>7} {'skipped':>7} {'t/o':>4} {'bus ms med':>10} {'bus ms max':>10}")
    for protocol in (1, 2):
        for delay in (500.0, 0.0):
            r = one(protocol, delay, a.duration, a.rate)
            print(f"{r['protocol']:>8} {r['return_delay_us']:>8g} {r['ticks']:>6} {r['rate_Hz']:>8.3f} "
                  f"{r['late_rms_ms']:>11.3f} {r['late_p99_ms']:>7.3f} {r['late_max_ms']:>7.3f} {r['skipped']:>7} "
                  f"{r['timeouts']:>4} {r['bus_ms_median']:>10.2f} {r['bus_ms_max']:>10.2f}", flush=True)


if __name__ == "__main__":
    main()
