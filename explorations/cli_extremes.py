"""Every command of the CLI under extreme and malformed values: does each end in one of its promised ways?

Promised: exit 0 with its output; exit 2 with one line naming the option and nothing written; exit 1
with a diagnosis for a simulation that diverged (``error: simulation diverged ...``), or with one line
for a file that could not be written (``error: could not write ...``, nothing left).  Anything else --
a traceback, another exit code, a refusal of several lines, a file left by a refusal -- is flagged.
Each value runs in a fresh process (``undulate ...``), four at a time, in folders under ``--work``.

    python explorations/cli_extremes.py --work /tmp/cli_extremes --out explorations/results/cli_extremes.md

A sweep of this kind (2026-12-02) found seventeen faults (a traceback, a wrong option named, a run of
nothing, a misleading diagnosis); each is now a test (tests/test_cli_validation.py, test_animate.py,
test_track.py, test_sweep.py, test_timestep_contact.py).  About 5 minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import itertools
import shutil
import subprocess
import sys
import time
from pathlib import Path

BAD_NUMBERS = ["nan", "inf", "-inf", "-1", "0", "-0", "1e300", "1e-300", "1e20", "abc", ""]
SIMULATE_OPTIONS = ["--links", "--waves-per-body", "--amplitude", "--frequency", "--channel-width", "--dx0",
                    "--separating-force", "--duration", "--timestep", "--sample-rate", "--body-length", "--width",
                    "--coupling", "--control-rate"]


def cases(work: Path) -> list[list[str]]:
    run, video, exp = str(work / "run.nc"), str(work / "video.mp4"), str(work / "exp.nc")
    bad_nc = str(work / "not-netcdf.nc")
    sim = ["simulate", "--phases", "0,90", "--duration", "0.5"]
    out = [[*sim, o, v] for o in SIMULATE_OPTIONS for v in BAD_NUMBERS]
    out += [["simulate", "--phases", v, "--duration", "0.5"]
            for v in ["", "0,", ",", "nan,0", "0;90", "0,90,abc", "1e400,0", "0," * 300 + "0", "-720,1e10"]]
    out += [[*sim, "--controller", v] for v in ["bogus", "", "PHASE-OSCILLATOR"]]
    out += [[*sim, *a] for a in (["--backend", "gpu"], ["--device", "cuda"], ["--backend", "warp", "--device", "tpu"],
                                  ["--out", "/nonexistent/x.nc"], ["--out", str(work)], ["--out", str(work / "x.txt")],
                                  ["--frequency", "1e12"], ["--links", "2000"], ["--sample-rate", "0.1"])]
    for ctl, hold, links in itertools.product(["open-loop", "self-oscillating", "phase-oscillator", "relay"],
                                              [False, True], [2, 5]):
        out.append(["simulate", "--phases", "0,90", "--duration", "2", "--controller", ctl, "--links", str(links)]
                   + (["--hold-x"] if hold else []) + (["--coupling", "5"] if ctl == "phase-oscillator" else []))
    out += [["animate", run, "--out", "{d}/a.gif", o, v]
            for o, v in [("--stride", "0"), ("--stride", "999999999999999999999"), ("--fps", "0"), ("--fps", "nan"),
                         ("--fps", "1e-300"), ("--fps", "1e300"), ("--fps", "101")]]
    out += [["animate", f, "--out", "{d}/a.gif"] for f in (bad_nc, "/nonexistent.nc", str(work))]
    out += [["animate", run, "--out", o] for o in ("{d}/a.png", "/nonexistent/a.gif", "/proc/a.gif", "/proc/a.mp4")]
    track = ["track", video, "--robots", "2", "--phases", "0,90", "--out", "{d}/t.nc"]
    out += [[*track, o, v] for o, v in [("--robots", "0"), ("--robots", "1000"), ("--start-time", "nan"),
                                        ("--calibration-window", "0"), ("--links", "1"), ("--amplitude", "100"),
                                        ("--channel-width", "-1"), ("--calibration", "/nonexistent.toml"),
                                        ("--calibration", bad_nc), ("--gait-from", bad_nc), ("--body-length", "1e300"),
                                        ("--out", "/proc/t.nc")]]
    out += [["track", f, "--robots", "2", "--out", "{d}/t.nc"] for f in ("/nonexistent.mp4", bad_nc)]
    out += [["compare", f, "--out", "{d}/cmp"] for f in (bad_nc, "/nonexistent.nc", run, exp)]
    out += [["compare", exp, "--out", "{d}/cmp", "--periods", v] for v in ("0", "1000000", "abc")]
    out += [["compare", exp, "--out", o] for o in ("/proc/cmp", str(work / "run.nc") + "/cmp")]
    out += [["reproduce", "--out", "{d}/r", *a] for a in (["--only", ""], ["--only", "bogus"], ["--animation-s", "0"],
                                                         ["--animation-s", "1e300"], ["--workers", "100000"],
                                                         ["--scheduler", "notaurl"], ["--seed", "-1"])]
    out += [["study", n, "--out", "{d}/s"] for n in ("bogus", "")]
    out += [["study", "compatibility", "--out", o] for o in ("/proc/s", run + "/s")]
    robot = ["robot", "run", "--ids", "1,2,3,4", "--dry-run", "--out", "{d}/r.nc", "--duration", "2"]
    out += [[*robot, o, v] for o, v in [("--protocol", "3"), ("--baudrate", "123"), ("--phases", "nan"),
                                        ("--links", "100"), ("--frequency", "1e6"), ("--control-rate", "1e9"),
                                        ("--servo", "MX-64"), ("--duration", "1e300"), ("--ids", "1,1,2,3"),
                                        ("--ids", "300,1,2,3"), ("--body-length", "1e300")]]
    out += [["robot", "ping", "--port", p] for p in ("/nonexistent/tty", "")]
    return out


def inputs(work: Path) -> None:
    """The files the cases read: a 2 s pair run, its filmed video, the video tracked, a file that is not netCDF."""
    import xarray as xr

    from undulate.track import render_video

    subprocess.run(["undulate", "simulate", "--phases", "0,90", "--duration", "2", "-q", "--out",
                    str(work / "run.nc")], check=True)
    render_video(xr.load_dataset(work / "run.nc"), work / "video.mp4")
    subprocess.run(["undulate", "track", str(work / "video.mp4"), "--robots", "2", "--phases", "0,90", "-q",
                    "--out", str(work / "exp.nc")], check=True)
    (work / "not-netcdf.nc").write_text("not netCDF\n")


def judge(rc, text: str, files: list[str]) -> str:
    lines = [line for line in text.splitlines() if line.strip()]
    if "Traceback" in text:
        return "traceback"
    if rc == 0:
        return "ok"
    if rc == 2:
        return "refused" if lines and lines[-1].startswith("error:") and not files else "refused badly"
    if rc == 1 and "error: simulation diverged" in text:
        return "diagnosed"
    if rc == 1 and len(lines) == 1 and lines[0].startswith("error: could not write") and not files:
        return "write refused"
    return f"exit {rc}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, required=True, help="scratch folder (emptied)")
    ap.add_argument("--out", type=Path, help="write the table here (markdown)")
    args = ap.parse_args()
    work = args.work.resolve()
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    inputs(work)
    todo = cases(work)

    def one(i_case):
        i, case = i_case
        d = work / f"case{i:03d}"
        d.mkdir()
        argv = [a.replace("{d}", str(d)) for a in case]
        if argv[0] == "simulate" and "--out" not in argv:
            argv += ["--out", str(d / "run.nc"), "-q"]
        try:
            p = subprocess.run(["undulate", *argv], capture_output=True, text=True, timeout=300, cwd=d)
            rc, text = p.returncode, p.stdout + p.stderr
        except subprocess.TimeoutExpired:
            rc, text = "timeout", ""
        files = [f.name for f in d.iterdir()]
        return argv, judge(rc, text, files if rc in (1, 2) else []), text

    t0 = time.perf_counter()
    with cf.ThreadPoolExecutor(4) as ex:
        results = list(ex.map(one, enumerate(todo)))
    counts: dict[str, int] = {}
    flagged = []
    for argv, verdict, text in results:
        counts[verdict] = counts.get(verdict, 0) + 1
        if verdict not in ("ok", "refused", "diagnosed", "write refused"):
            last = [line for line in text.splitlines() if line.strip()][-1:] or [""]
            flagged.append(f"| `{' '.join(a[:40] for a in argv)}` | {verdict} | {last[0][:160]} |")
    lines = [f"# CLI extremes ({len(results)} cases, {time.perf_counter() - t0:.0f} s)", "",
             "| outcome | cases |", "|---|---:|", *[f"| {k} | {v} |" for k, v in sorted(counts.items())], ""]
    lines += ["| flagged command | outcome | last line |", "|---|---|---|", *flagged] if flagged else ["Nothing flagged."]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text)
    return 1 if flagged else 0


if __name__ == "__main__":
    sys.exit(main())
