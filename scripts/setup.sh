#!/usr/bin/env bash
# Create .venv (once) with HeartPole and its extras: all of them (what scripts/test.sh needs) by default, or
# those given, e.g. `bash scripts/setup.sh train` (what scripts/main.sh needs: training and evaluating, about
# 2 minutes on a fresh machine instead of 6). A .venv set up with fewer extras gets the others on a later call.
# PyTorch comes first where an extra needs it, pinned to the local CPU build (torch==2.13.0), so that
# stable-baselines3 does not pull the multi-GB CUDA build.
set -euo pipefail
cd "$(dirname "$0")/.."
extras="${1:-all}"
if [[ ! "$extras" =~ ^[a-z]+(,[a-z]+)*$ ]]; then
  echo "scripts/setup.sh: extras are names separated by commas (train, plot, offline, ray, jax, mo, docs, test, all), got '$extras'" >&2
  exit 2
fi
if [ ! -x .venv/bin/python ]; then
  python3 -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
if [[ ",$extras," =~ ,(all|train|ray|test), ]]; then  # the extras that bring Stable-Baselines3, hence PyTorch
  .venv/bin/python -m pip install -q torch==2.13.0
fi
.venv/bin/python -m pip install -q -e ".[$extras]"
# Compile the steps, the optimum's programs and its history policy once into numba's disk cache (beside the
# sources), as pip compiles .pyc files, and solve v0's optimum into the optimum cache ($HEARTPOLE_CACHE_DIR, else the
# user's): test workers and the first commands then load them instead of each compiling and solving the same.
.venv/bin/python -W ignore -c '
import warnings, gymnasium as gym, heartpole
warnings.simplefilter("ignore")  # after gymnasium, which sets its own filters: v0 is "out of date"
for env_id in ("HeartPole-v0", "HeartPole-v1"):
    for people in (None, "default"):
        for env in (gym.make(env_id, people=people), gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", people=people)):
            env.reset(seed=0)
            env.step(env.action_space.sample())
from heartpole.optimum import optimum, solve
import numpy as np
# a short day: its drinks need the lifetime check, so every program of a no-drink solve is compiled (about a minute)
solve("HeartPole-v0", max_steps=40)
# the v0 optimum, solved once into the optimum cache as the first evaluate would (about 15 s), and its history policy
optimum("HeartPole-v0").history.sleeps(np.zeros((1, 6)), np.array([40]))
'
