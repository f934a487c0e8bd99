#!/usr/bin/env bash
# The body calibrated from the films themselves (docs/body.md, "The motion model's subject" and
# "Limb lengths from the keypoints, radii from the silhouettes"): each film's videos tracked by
# MRPF at budget 500 with the 2-D keypoints summed in (`--likelihood silhouette+keypoints`),
# started automatically, the body calibrated from the first 4 frames (`--body auto`) under each
# `--body-prior`, then scored against the film's truth.npz: one line per run,
#   film prior seed mean-error-mm frame-0-error-mm
# Usage: bash experiments/calibrated_body_films.sh FILM_DIR ...   (each made by `jaxtrack scene
#   TAKE.npz --rgb --video FILM_DIR --width 320 --height 240 --views 4 --frames N`)
# Env: MODEL (a walk manifold, e.g. video_tracking.sh's walk.eqx), VALIDATION (its validation take,
#   the donor of --body-prior proportions and motion), OUT, PRIORS, SEEDS, LIKELIHOOD.
set -euo pipefail
MODEL=${MODEL:-/tmp/video_study/walk.eqx}
VALIDATION=${VALIDATION:-/tmp/cmu/35_03.npz}
OUT=${OUT:-/tmp/calibrated_body}
PRIORS=${PRIORS:-"default proportions motion"}
SEEDS=${SEEDS:-"0 1"}
LIKELIHOOD=${LIKELIHOOD:-silhouette+keypoints}
mkdir -p "$OUT"
for film in "$@"; do
  name=$(basename "$film")
  cams=$(python -c "import json;print(' '.join('$film/'+c['name']+'.mp4' for c in json.load(open('$film/calibration.json'))['cameras']))")
  bgs=$(python -c "import json;print(' '.join('$film/background/'+c['name']+'.mp4' for c in json.load(open('$film/calibration.json'))['cameras']))")
  cue=()
  [ "$LIKELIHOOD" = silhouette ] || cue=(--keypoints "$film/keypoints.npz" --likelihood "$LIKELIHOOD")
  for prior in $PRIORS; do
    for seed in $SEEDS; do
      run="$OUT/${name}_${LIKELIHOOD}_${prior}_s${seed}.npz"
      [ -f "$run" ] || jaxtrack track --video $cams --background $bgs --calibration "$film/calibration.json" \
          --model "$MODEL" --validation "$VALIDATION" --method mrpf --chunk-frames 0 --body auto --body-prior "$prior" \
          ${cue[@]+"${cue[@]}"} --seed "$seed" --out "$run" > "$run.log" 2>&1
      python -c "
import numpy as np
from jaxtrack.io import load_sequence
truth = load_sequence('$film/truth.npz').joints3d
estimate = load_sequence('$run').joints3d
error = 1000 * np.linalg.norm(estimate - truth[:len(estimate)], axis=-1).mean(-1)
print('$name', '$prior', '$seed', round(float(error.mean()), 1), round(float(error[0]), 1))"
    done
  done
done
