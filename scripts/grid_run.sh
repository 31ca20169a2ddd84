#!/usr/bin/env bash
# The full grid for one planner, in N resumable chunks (docs/evaluation.md, "The full grid").
# Each chunk's compact table lands in results/grid/ as it finishes (commit it); chunks
# already there are skipped, and a stopped chunk resumes from the working store.
#   scripts/grid_run.sh PLANNER [N=64] [WORKERS=2]   (about 1,100 cases a chunk)
set -euo pipefail
planner=${1:?planner name}
n=${2:-64}
workers=${3:-2}
for k in $(seq 1 "$n"); do
  f=$(printf 'results/grid/%s-chunk%02d-of-%02d.parquet' "$planner" "$k" "$n")
  [ -f "$f" ] && continue
  mirrorpark evaluate --planner "$planner" --sample full --chunk "$k/$n" \
    --out "results/grid-runs/$planner" --export results/grid --workers "$workers" --quiet --json
done
