#!/usr/bin/env bash
# Paper 000's protocol (sec. 6, ../shared/METHODS.md sec. 4) on real motion of one subject:
# CMU subject 35 (../shared/data/cmu35, GPmat's 30 Hz trials) converted to HumanEva poses at
# HumanEva's 60 Hz, the test trials rendered into 4 noisy 80x60 silhouette views. One manifold
# per activity, trained on two trials, dynamics fitted on a third, tested on a held-out
# trial (35_29 walk, first 200 frames; 35_18 jog, all of it).
#
#   bash benchmarks/cmu_experiment.sh [OUT]          (RUNS=5 BUDGET=500 by default)
#
# Writes OUT/walk and OUT/jog (results.json, table.md, error_curves.png, overlay GIFs).
set -euo pipefail
DATA=${DATA:-../shared/data/cmu35}
OUT=${1:-cmu_experiment}
RUNS=${RUNS:-5}
BUDGET=${BUDGET:-500}
if [ ! -d "$DATA" ]; then echo "no CMU data at $DATA (set DATA=...)" >&2; exit 2; fi
mkdir -p "$OUT"
[ -f "$OUT/amc/35_29.amc" ] || python "$(dirname "$0")/cmu_trials_to_amc.py" "$OUT/amc" --data "$DATA"
for trial in 01 02 03 29 17 19 20 21 18 04 22; do  # 04, 22: real_motion.py --sequences held-out
    [ -f "$OUT/35_$trial.npz" ] || jaxtrack convert "$OUT/amc/35_$trial.amc" "$OUT/35_$trial.npz" --source-fps 30 --fps 60
done
[ -f "$OUT/walk_test.npz" ] || jaxtrack scene "$OUT/35_29.npz" "$OUT/walk_test.npz" --frames 200 --seed 1
[ -f "$OUT/jog_test.npz" ] || jaxtrack scene "$OUT/35_18.npz" "$OUT/jog_test.npz" --seed 2
jaxtrack experiment --train "$OUT/35_01.npz" "$OUT/35_02.npz" --validation "$OUT/35_03.npz" \
    --test "$OUT/walk_test.npz" --runs "$RUNS" --budget "$BUDGET" --out "$OUT/walk"
jaxtrack experiment --train "$OUT/35_17.npz" "$OUT/35_19.npz" "$OUT/35_20.npz" --validation "$OUT/35_21.npz" \
    --test "$OUT/jog_test.npz" --runs "$RUNS" --budget "$BUDGET" --out "$OUT/jog"
