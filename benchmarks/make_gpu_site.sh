#!/usr/bin/env bash
# Builds what the GPU check carries to a device machine without a package registry (docs/gpu.md):
# the cp312 wheels of the gpu extra and of what that machine's image lacks, unpacked into one site
# directory, warp-clang.so (Warp's CPU compiler) and test data left out, as an xz tarball split in
# two parts under 57 MB (a call carries 64 MiB with the working tree):
#
#   benchmarks/make_gpu_site.sh [OUTDIR=out/site] [KERNELS]   # then out/site/part.00, out/site/part.01
#
# KERNELS: what benchmarks/bench_gpu_kernels.py wrote (Warp's GPU kernels compiled here); they go into
# the site as warp-kernels/, and gpu_check.sh copies them into the device's kernel cache.
# On 2026-11-27 (no kernels): 91 MB in all, about 2 minutes on 2 cores; on 2026-11-28 with the full
# reproduction's kernels: 96 MB, two 48 MB parts.
set -eu
OUT=${1:-out/site}
KERNELS=${2:-}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
PLAT=(--only-binary=:all: --python-version 3.12 --platform manylinux_2_28_x86_64)
pip download -q --no-deps "${PLAT[@]}" -d "$TMP/wheels" mujoco==3.17.0 mujoco-warp==4.0.0 warp-lang==1.19.0 \
    h5netcdf websockets glfw PyOpenGL
pip install -q --no-index --no-deps "${PLAT[@]}" --target "$TMP/site" "$TMP"/wheels/*.whl
rm -rf "$TMP"/site/warp/bin/warp-clang.so "$TMP"/site/warp/examples "$TMP"/site/warp/tests \
    "$TMP"/site/mujoco_warp/test_data "$TMP"/site/mujoco/experimental
find "$TMP/site" -name __pycache__ -prune -exec rm -rf {} +
if [ -n "$KERNELS" ]; then
    mkdir -p "$TMP/site/warp-kernels"  # the cache folder and kernels.json (not the recorded batches.pkl)
    VER=$(python3 -c "import json, sys; print(json.load(open(sys.argv[1]))['cache_dir'])" "$KERNELS/kernels.json")
    cp -r "$KERNELS/kernels.json" "$KERNELS/$VER" "$TMP/site/warp-kernels/"
fi
mkdir -p "$OUT"
rm -f "$OUT"/part.*
tar cf - -C "$TMP/site" . | xz -T0 -6 > "$TMP/site.tar.xz"
split -n 2 -d "$TMP/site.tar.xz" "$OUT/part."
ls -l "$OUT"
# a call carries 64 MiB with the working tree (~7 MB): each part must stay under 57 MB
for p in "$OUT"/part.*; do
    [ "$(stat -c %s "$p")" -lt 57000000 ] || { echo "make_gpu_site: $p is over 57 MB"; exit 1; }
done
