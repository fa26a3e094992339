"""A full disk, a quota or a file-size limit while writing: one line naming the file, exit code 1, nothing
half-written left, and no crash (``undulate._io.hdf5_writes``, ``undulate.errors.WriteError``).

Found by running ``undulate simulate`` onto a 3 MB tmpfs: a page of h5py "Exception ignored" tracebacks,
then a segmentation fault; a disk that filled mid-run was worse: HDF5 reported its failed writes only
in finalizers, the run went on, and the corrupt file was renamed into place as if whole before the
crash.  Real write failures here: a file-size limit (``RLIMIT_FSIZE``: every write past it fails with
EFBIG, and freeing space does not help), and where this process may mount one, a small tmpfs filled
during the run (ENOSPC)."""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:  # workers inherit sys.path, so they can import sweep_funcs
    sys.path.insert(0, str(HERE))

import sweep_funcs  # noqa: E402

from undulate import Scene, SimOptions, simulate  # noqa: E402
from undulate.errors import WriteError  # noqa: E402
from undulate.simulation import _record  # noqa: E402
from undulate.sweep import Grid, run_sweep  # noqa: E402

resource = pytest.importorskip("resource")
_DISK_USAGE = shutil.disk_usage  # the real one (the tests replace it in the shutil module itself)

_LIMITED = textwrap.dedent("""
    import resource, sys
    limit = int(sys.argv[1])
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))  # CPython ignores SIGXFSZ: writes fail, EFBIG
    from undulate.cli import main
    sys.exit(main(sys.argv[2:]))
""")


@pytest.mark.parametrize("limit_bytes", [20_000, 300_000, 2_000_000],
                         ids=["the-first-write", "an-early-append", "a-later-append"])
def test_a_file_size_limit_ends_simulate_with_one_line_and_no_file(tmp_path, limit_bytes):
    """Every write past the limit fails: the file's first bytes, an append, or one further on.  Before:
    exit 139 (a segmentation fault) after the error; HDF5 could not close the file at exit."""
    r = subprocess.run([sys.executable, "-c", _LIMITED, str(limit_bytes), "simulate", "--duration", "3000", "-q",
                        "--out", str(tmp_path / "run.nc")], capture_output=True, text=True, timeout=300,
                       cwd=tmp_path)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1, r.stderr[-3000:]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr[-3000:]
    assert lines[0].startswith(f"error: could not write {tmp_path / 'run.nc'}: File too large")
    assert lines[0].endswith("nothing was written")
    assert list(tmp_path.iterdir()) == []


def _filling(monkeypatch, free_after: int, folder: Path, at_once: bool = False):
    """``shutil.disk_usage`` as the recorder sees it: ``free_after`` bytes free once the run has begun
    writing into ``folder`` (its temporary file is there), or ``at_once``."""
    def usage(path):
        u = _DISK_USAGE(path)
        return u._replace(free=free_after) if at_once or list(folder.glob(".*.tmp")) else u

    monkeypatch.setattr(_record.shutil, "disk_usage", usage)


def test_a_disk_that_fills_during_a_run_stops_it_before_hdf5_meets_it(tmp_path, monkeypatch):
    """The free space is checked before each append: under the margin, WriteError (ENOSPC) and the
    temporary file removed; the simulation does not go on to the end."""
    _filling(monkeypatch, free_after=1 << 20, folder=tmp_path)
    t0 = time.perf_counter()
    with pytest.raises(WriteError, match="No space left on device: the disk filled during the run") as e:
        simulate(Scene(phases_rad=(0.0, 1.0)), SimOptions(duration_s=400.0, sample_rate_hz=500.0),
                 out=tmp_path / "run.nc")
    assert e.value.errno == errno.ENOSPC and e.value.disk_full and e.value.filename == str(tmp_path / "run.nc")
    assert time.perf_counter() - t0 < 60
    assert list(tmp_path.iterdir()) == []


def test_simulate_cli_on_a_full_disk_says_so_in_one_line(tmp_path, monkeypatch, capfd):
    from undulate.cli import main

    _filling(monkeypatch, free_after=0, folder=tmp_path, at_once=True)  # refused before stepping
    assert main(["simulate", "--duration", "30", "-q", "--out", str(tmp_path / "a.nc")]) == 2
    assert "fit on disk" in capfd.readouterr().err
    _filling(monkeypatch, free_after=1 << 20, folder=tmp_path)  # filled during the run
    assert main(["simulate", "--duration", "400", "--sample-rate", "500", "-q", "--out", str(tmp_path / "b.nc")]) == 1
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: could not write {tmp_path / 'b.nc'}: No space left"), err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("phases, duration_s, rate_hz", [((0.0, 1.57), 30.0, 20.0), ((0.0, 1.0, 2.0, 3.0, 4.0, 5.0), 30.0, 20.0),
                                                      ((0.0, 1.57), 300.0, 500.0)])
def test_a_streamed_file_is_about_its_samples_and_within_the_disk_check(tmp_path, phases, duration_s, rate_hz):
    """HDF5 stores chunks whole: a 30 s pair run in 1 MiB chunks was a 13.7 MB file of 0.2 MB of samples.
    Chunks no longer than the run: the file is its samples plus about 70 kB, and the bound the disk
    check uses (``_file_bytes``) holds."""
    from undulate.simulation import compile_scene, resolve_options

    scene = Scene(phases_rad=phases)
    options = SimOptions(duration_s=duration_s, sample_rate_hz=rate_hz)
    with simulate(scene, options, out=tmp_path / "run.nc") as ds:
        data = sum(v.nbytes for v in ds.variables.values())
        n = ds.sizes["time"]
    size = (tmp_path / "run.nc").stat().st_size
    resolved = resolve_options(scene, options)
    bound = _record._file_bytes(compile_scene(scene, resolved), resolved.recorded, n)
    assert data < size <= bound, (data, size, bound)
    assert size < data + (data if n < 2000 else 0.3 * data) + 200_000, (data, size)


@pytest.mark.parametrize("where", ["local", "dask"])
def test_a_full_disk_stops_a_sweep_and_the_same_sweep_resumes(tmp_path, where):
    """A run that meets a full disk ends the sweep with its WriteError (across the worker processes, or
    from a Dask task), recorded as no run's failure; with space again, the same sweep computes only
    what is missing."""
    flag = tmp_path / "disk-is-full"
    flag.touch()
    grid = Grid(axes={"damping_Nms": [0.1, 0.2, 0.5, 1.0, 2.0, 3.0], "length_m": [0.5], "full_flag": [str(flag)]},
                seed=0)
    out = tmp_path / "sweep"
    with contextlib.ExitStack() as stack:
        if where == "dask":
            distributed = pytest.importorskip("distributed")
            cluster = stack.enter_context(distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                                                   dashboard_address=None))
            kw = {"scheduler": cluster.scheduler_address}
        else:
            kw = {"workers": 2}
        with pytest.raises(WriteError) as e:
            run_sweep(sweep_funcs.pendulum_disk_full, grid, out, progress=False, **kw)
        assert e.value.disk_full and "No space left on device" in str(e.value)
        assert not list((out / "runs").glob("*failed*"))
        assert len(list((out / "runs").glob("*.nc"))) <= 3
        flag.unlink()
        result = run_sweep(sweep_funcs.pendulum_disk_full, grid, out, progress=False, **kw)
    result.raise_if_failed()
    assert result.dataset.sizes["damping_Nms"] == 6
    assert np.isfinite(result.dataset["final_angle"].values).all()


def _can_mount_tmpfs(where: Path) -> bool:
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    where.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64m", "tmpfs", str(where)], capture_output=True)
    return r.returncode == 0


def test_a_real_disk_filling_during_simulate(tmp_path):
    """A 64 MB tmpfs filled by another file once the run has started: exit 1, one line, no file of the
    run left, no crash (where this process may mount a tmpfs; before: exit 139)."""
    disk = tmp_path / "disk"
    if not _can_mount_tmpfs(disk):
        pytest.skip("mounting a tmpfs needs root (and the permission to mount)")
    try:
        proc = subprocess.Popen([sys.executable, "-m", "undulate.cli", "simulate", "--duration", "6000", "-q",
                                 "--out", str(disk / "run.nc")], stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None and not list(disk.glob(".*.tmp")):
            time.sleep(0.05)
        time.sleep(0.5)
        with open(disk / "filler", "wb") as f:  # fill it
            try:
                while True:
                    f.write(b"\0" * (1 << 20))
                    f.flush()
            except OSError:
                pass
        _, err = proc.communicate(timeout=300)
        lines = [line for line in err.strip().splitlines() if not line.startswith("estimated compute time")]
        assert proc.returncode == 1 and len(lines) == 1 and "Traceback" not in err, err[-3000:]
        assert lines[0].startswith(f"error: could not write {disk / 'run.nc'}: No space left on device"), lines
        assert sorted(p.name for p in disk.iterdir()) == ["filler"]
    finally:
        subprocess.run(["umount", "-l", str(disk)], capture_output=True)
