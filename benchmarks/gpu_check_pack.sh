#!/usr/bin/env bash
# The GPU check's figures from DIR into OUT as two files: gpu_check.json and figures.tgz (the logs, the
# Warp first-step records and each reproduction's JSON files: claims, reproduce and every finished study's
# NAME.json; not its netCDF or figures). The device machine returns at most 8 files from $OUT, so a
# reproduction's study files copied one by one were cut (2026-11-27); one archive keeps them all.
#
#   benchmarks/gpu_check_pack.sh DIR OUT
set -u
DIR=${1:?usage: gpu_check_pack.sh DIR OUT}
OUT=${2:?usage: gpu_check_pack.sh DIR OUT}
mkdir -p "$OUT"
cd "$DIR" || exit 1
cp gpu_check.json "$OUT"/ 2>/dev/null
files=$(ls gpu_check.json ./*.log ./*.jsonl repro-*/*.json 2>/dev/null)
[ -n "$files" ] && tar czf "$OUT/figures.tgz" $files
ls -l "$OUT"
[ -f "$OUT/figures.tgz" ] && tar tzf "$OUT/figures.tgz" | wc -l | sed 's/$/ files in figures.tgz/'
exit 0
