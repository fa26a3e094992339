"""The MuJoCo backend's verdicts of reproductions, as the GPU check compares them (issue 37).

    python benchmarks/bench_gpu_check_reference.py OUT.json quick=REPRO_DIR [full=REPRO_DIR ...]

Reads each reproduction folder's ``claims.json`` and ``reproduce.json`` and writes
``{mode: {"verdicts": {"study:claim": verdict}, "wall_s": ..., "commit": ..., "src_tree": ...,
"src_sha256": ...}}``: the reference
``benchmarks/gpu_check.sh --cpu-verdicts OUT.json`` compares the Warp backend's verdicts against, so
the device's minutes are not spent re-running the CPU reproductions.  MuJoCo's results are a
function of the code, the parameters and the seed, so the reference must come from the commit the
check runs, or one whose reproduction code is the same: the digest of the files a reproduction runs
(:func:`reproduction_files`), which the check compares with its own (``cpu_reference_same_code``).
The commit and its ``src`` tree (``git rev-parse COMMIT:src``) are recorded too.
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src" / "undulate"


ENTRY_FILES = ("__init__.py", "cli.py", "_cliutil.py")
"""The command line's own files, hashed as they are (their imports are not followed: the robot's and
the tracker's commands it mounts do not run in a reproduction): the ``reproduce`` command's options
and their defaults."""


def reproduction_files(root: Path = SRC) -> list[str]:
    """The package files (paths under ``root``, sorted) a reproduction's MuJoCo results and verdicts
    come from: ``undulate.reproduce`` and every study module (the study registry imports each public
    module of ``undulate.studies`` by name), with every ``undulate`` module they import, at the top or
    inside a function (:func:`undulate._source.closure`, the import graph a sweep's code hash follows),
    and :data:`ENTRY_FILES`.  The Warp backend's modules are left out, as from a MuJoCo sweep's code
    hash (``undulate._source.BACKEND_MODULES``).  The robot driver, the tracker, plotting and the
    report are not reached, so an edit there leaves the reference valid."""
    from undulate._source import BACKEND_MODULES, closure, import_graph, module_files

    files = module_files(root)
    graph = import_graph(root)
    studies = [m for m in files if m.startswith("undulate.studies.") and m.count(".") == 2
               and not m.rsplit(".", 1)[1].startswith("_")]
    mods = closure(["undulate.reproduce", *studies], graph) - set(BACKEND_MODULES["warp"])
    paths = {files[m].relative_to(root).as_posix() for m in mods} | set(ENTRY_FILES)
    return sorted(paths)


def src_digest(root: Path = SRC) -> str:
    """SHA-256 of :func:`reproduction_files` (paths and contents, in order): the same on the device
    machine, which has no git, as here for code whose MuJoCo reproductions are the same."""
    h = hashlib.sha256()
    for rel in reproduction_files(root):
        h.update(rel.encode() + b"\0" + (root / rel).read_bytes() + b"\0")
    return h.hexdigest()


def main(argv: list[str]) -> int:
    out, pairs = Path(argv[0]), [a.split("=", 1) for a in argv[1:]]
    def git(*args: str) -> str:
        return subprocess.run(["git", *args], capture_output=True, text=True, cwd=Path(__file__).parent).stdout.strip()

    # the package's source tree: a later commit that changes only docs or benchmarks has the same one,
    # and its MuJoCo results are these
    commit, src_tree = git("rev-parse", "HEAD"), git("rev-parse", "HEAD:src")
    doc = {}
    for mode, folder in pairs:
        d = Path(folder)
        claims = json.loads((d / "claims.json").read_text())
        state = json.loads((d / "reproduce.json").read_text())
        doc[mode] = {"verdicts": {f"{c.get('study')}:{c.get('claim')}": c.get("verdict") for c in claims["claims"]},
                     "wall_s": state.get("wall_s"), "commit": commit, "src_tree": src_tree, "src_sha256": src_digest(),
                     "studies": {k: v.get("wall_s") for k, v in state.get("studies", {}).items()}}
    out.write_text(json.dumps(doc, indent=1))
    print(f"wrote {out}: " + ", ".join(f"{m} {len(v['verdicts'])} claims" for m, v in doc.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
