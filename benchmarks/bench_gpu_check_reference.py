"""The MuJoCo backend's verdicts of reproductions, as the GPU check compares them (issue 37).

    python benchmarks/bench_gpu_check_reference.py OUT.json quick=REPRO_DIR [full=REPRO_DIR ...]

Reads each reproduction folder's ``claims.json`` and ``reproduce.json`` and writes
``{mode: {"verdicts": {"study:claim": verdict}, "wall_s": ..., "commit": ..., "src_tree": ...,
"src_sha256": ...}}``: the reference
``benchmarks/gpu_check.sh --cpu-verdicts OUT.json`` compares the Warp backend's verdicts against, so
the device's minutes are not spent re-running the CPU reproductions.  MuJoCo's results are a
function of the code, the parameters and the seed, so the reference must come from the commit the
check runs, or one with the same ``src`` tree (``git rev-parse COMMIT:src``; both recorded here, and
the sources' digest, which the check compares with its own: ``cpu_reference_same_code``).
"""

from __future__ import annotations

import hashlib
import json
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src" / "undulate"


def _warp_files() -> set[str]:
    """The Warp backend's modules (``undulate._source.BACKEND_MODULES["warp"]``) as paths under the
    package: left out of the digest, as out of a MuJoCo sweep's code hash, since the MuJoCo backend's
    results do not depend on them."""
    from undulate._source import BACKEND_MODULES

    return {m.split(".", 1)[1].replace(".", "/") + ".py" for m in BACKEND_MODULES["warp"]}


def src_digest(root: Path = SRC) -> str:
    """SHA-256 of the package's Python sources but the Warp backend's (paths and contents, in order):
    the same on the device machine, which has no git, as here for code whose MuJoCo results are the same."""
    h, warp = hashlib.sha256(), _warp_files()
    for f in sorted(root.rglob("*.py")):
        if f.relative_to(root).as_posix() not in warp:
            h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
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
