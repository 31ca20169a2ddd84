#!/usr/bin/env bash
# The full grid for one planner, in N resumable chunks (docs/evaluation.md, "The full grid").
# Each chunk's compact table lands in DIR as it finishes (commit it); chunks already there
# are skipped, and a stopped chunk resumes from its working store under results/grid-runs/.
#   scripts/grid_run.sh PLANNER [N=64] [WORKERS=2] [DIR=results/grid] [EVALUATE OPTIONS...]
# (about 1,100 cases a chunk). Options after DIR go to every `mirrorpark evaluate`, e.g.
# --mixed-code to resume a stopped chunk after a change to code that decides no row of it.
# A rerun of a changed planner goes to a folder of its own (e.g. results/grid/<commit>), so
# that one set of tables never mixes two planner codes.
set -euo pipefail
planner=${1:?planner name}
n=${2:-64}
workers=${3:-2}
dir=${4:-results/grid}
shift $(($# < 4 ? $# : 4))
store="results/grid-runs/$planner"
[ "$dir" = results/grid ] || store="results/grid-runs/$(basename "$dir")/$planner"
mkdir -p "$dir"
for k in $(seq 1 "$n"); do
  f=$(printf '%s/%s-chunk%02d-of-%02d.parquet' "$dir" "$planner" "$k" "$n")
  [ -f "$f" ] && continue
  mirrorpark evaluate --planner "$planner" --sample full --chunk "$k/$n" \
    --out "$store" --export "$dir" --workers "$workers" --quiet --json "$@"
done
