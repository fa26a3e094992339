#!/usr/bin/env bash
# The last call of a device lease's setup (docs/gpu.md, "A lease step by step"): the calls before it
# copied out/site/part.00 (and any parts but the last) to /tmp/parts; this one carries the last part,
# runs the GPU check in /tmp/gc
# and copies its figures to $OUT every 10 s (a run cut short still returns them), and at the end packs
# them with the logs and the reproductions' study files (benchmarks/gpu_check_pack.sh).
#
#   benchmarks/gpu_check_lease.sh BUDGET_S HARD_STOP_S [bench_gpu_check.py options]
set -u
BUDGET=${1:?usage: gpu_check_lease.sh BUDGET_S HARD_STOP_S [options]}
HARD=${2:?usage: gpu_check_lease.sh BUDGET_S HARD_STOP_S [options]}
shift 2
: "${OUT:?the device machine sets OUT}"
mkdir -p /tmp/parts && cp out/site/part.* /tmp/parts/ && ls -l /tmp/parts
GC=/tmp/gc
mkdir -p $GC
( while sleep 10; do cp $GC/gpu_check.json "$OUT"/ 2>/dev/null; done ) &
SAVER=$!
UNDULATE_SITE_PARTS="$(ls /tmp/parts/part.* | tr '\n' ' ')" timeout "$HARD" \
    "$(dirname "$0")/gpu_check.sh" $GC --budget-s "$BUDGET" "$@"
echo "gpu_check rc $?"
kill $SAVER 2>/dev/null
bash "$(dirname "$0")/gpu_check_pack.sh" $GC "$OUT"  # gpu_check.json and figures.tgz (8 files come back at most)
