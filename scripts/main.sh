#!/usr/bin/env bash
# The main job: set up .venv (once) with what it needs alone (HeartPole and its train extra: training and
# evaluating; scripts/test.sh adds the other extras), train an agent with the default (solving) settings, then
# evaluate it against the built-in baselines. Results land in runs/main/ (model, learning curve, evaluation,
# baselines.md/csv). Extra arguments go to `heartpole train`, e.g. --seed 3 or --timesteps 200000.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh train
out=runs/main
.venv/bin/heartpole train --out "$out" --force "$@"
.venv/bin/heartpole baselines --policy "$out/model.zip" --out "$out" --force
