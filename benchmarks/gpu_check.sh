#!/usr/bin/env bash
# The GPU check of issue 37, prepared to run once on a GPU machine without a package registry.
#
#   benchmarks/gpu_check.sh OUTDIR [bench_gpu_check.py options, e.g. --budget-s 450 --skip-full]
#
# Python packages the machine lacks (mujoco 3.17.0 for its Python, mujoco-warp, warp-lang, h5netcdf, ...)
# come as one xz tarball of an unpacked site directory, possibly split in parts (docs/gpu.md says how it
# is made): set UNDULATE_SITE_PARTS to the parts, in order.  Without it the packages must be importable.
# Prints as it goes; the figures go to OUTDIR/gpu_check.json (kept up to date), the reproductions' logs
# beside it.
set -u
OUTDIR=${1:?usage: benchmarks/gpu_check.sh OUTDIR [options]}
shift
HERE=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$OUTDIR"
if [ -n "${UNDULATE_SITE_PARTS:-}" ]; then
    SITE=${UNDULATE_SITE_DIR:-/tmp/undulate-site}
    mkdir -p "$SITE"
    t=$(date +%s)
    # shellcheck disable=SC2086
    cat $UNDULATE_SITE_PARTS | xz -d | tar x -C "$SITE" || { echo "gpu_check: unpacking the site failed"; exit 3; }
    echo "gpu_check: site unpacked in $(( $(date +%s) - t )) s"
    export PYTHONPATH="$SITE:$HERE/src${PYTHONPATH:+:$PYTHONPATH}"
else
    export PYTHONPATH="$HERE/src${PYTHONPATH:+:$PYTHONPATH}"
fi
export PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader 2>/dev/null | sed 's/^/gpu_check: /'
python3 -c "import warp, mujoco_warp, mujoco, undulate; print('gpu_check: imports ok, mujoco', mujoco.__version__)" \
    || { echo "gpu_check: the packages do not import"; exit 3; }
if [ -n "${SITE:-}" ] && [ -d "$SITE/warp-kernels" ]; then
    # Warp's GPU kernels compiled ahead of time (benchmarks/bench_gpu_kernels.py) into its kernel cache:
    # a module whose hash matches loads from there instead of compiling at a model's first step
    # (Warp's start-up banner may go to stdout too: the path is the last line)
    KCACHE=$(python3 -c "import warp; warp.config.quiet = True; warp.init(); print(warp.config.kernel_cache_dir)" | tail -n 1)
    VER=$(python3 -c "import json, sys; print(json.load(open(sys.argv[1]))['cache_dir'])" "$SITE/warp-kernels/kernels.json")
    if [ "${KCACHE#/}" != "$KCACHE" ] && mkdir -p "$KCACHE" && cp -rn "$SITE/warp-kernels/$VER"/. "$KCACHE"/; then
        export UNDULATE_PRECOMPILED_KERNELS=$(ls "$SITE/warp-kernels/$VER" | wc -l)
        echo "gpu_check: $UNDULATE_PRECOMPILED_KERNELS precompiled kernel modules copied to $KCACHE"
    else
        echo "gpu_check: copying the precompiled kernels to Warp's cache ($KCACHE) failed (they compile at first steps)"
    fi
fi
exec python3 "$HERE/benchmarks/bench_gpu_check.py" "$OUTDIR" "$@"
