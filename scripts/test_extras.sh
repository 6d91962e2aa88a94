#!/usr/bin/env bash
# Each extra installs what its commands import: every extra alone in a venv of its own (.venv-extras/<extra>,
# reused while pyproject.toml is unchanged), then one command of it, as README's install lines promise:
#   offline  heartpole dataset, its env recovered through Minari, and heartpole ope on it
#   plot     heartpole plot model
#   jax      heartpole.jax.make, a reset and a step
#   mo       mo_gymnasium.make("mo-heartpole-v0"), its vector reward scalarised by LinearReward into v0's reward
#   train    a tiny heartpole train
#   ray      a tiny heartpole train --ray over two seeds
#   docs     the documentation site's strict build (scripts/build_docs.sh)
# and one client that cannot share the dev venv:
#   d3rlpy   the offline extra with d3rlpy 2.8.0 (2.8.1 pins gymnasium==1.0.0; its gym dependency prints a notice
#            into every process that imports Stable-Baselines3): tests/test_clients.py's d3rlpy case
# The full dev venv hides a missing dependency (pillow came with matplotlib for Minari's HDF5 storage, say).
# PyTorch's CPU build goes in first where Stable-Baselines3 needs it (train, ray), as in scripts/setup.sh.
# Usage: bash scripts/test_extras.sh [--setup-only] [EXTRA ...]   (default: all eight; the installs run side by
# side). CI builds the venvs while the slow tests run (--setup-only), then runs the commands.
set -euo pipefail
cd "$(dirname "$0")/.."
setup_only=0
if [ "${1:-}" = "--setup-only" ]; then setup_only=1; shift; fi
extras=("$@")
[ ${#extras[@]} -gt 0 ] || extras=(offline plot jax mo train ray docs d3rlpy)
root=.venv-extras
stamp=$(sha256sum pyproject.toml | cut -d' ' -f1)

install() {  # a fresh venv with HeartPole and the one extra; its log in $root/<extra>.log
  local extra=$1 venv=$root/$1
  if [ -f "$venv/pyproject.sha256" ] && [ "$(cat "$venv/pyproject.sha256")" = "$stamp" ]; then return 0; fi
  rm -rf "$venv"
  python3 -m venv "$venv"
  case $extra in train | ray | d3rlpy) "$venv/bin/python" -m pip install -q torch==2.13.0 ;; esac
  case $extra in
    d3rlpy) "$venv/bin/python" -m pip install -q -e ".[offline]" d3rlpy==2.8.0 "pytest>=7" ;;
    *) "$venv/bin/python" -m pip install -q -e ".[$extra]" ;;
  esac
  echo "$stamp" > "$venv/pyproject.sha256"
}

mkdir -p "$root"
pids=()
for extra in "${extras[@]}"; do
  case $extra in
    offline | plot | jax | mo | train | ray | docs | d3rlpy) ;;
    *) echo "test_extras: unknown extra '$extra' (offline, plot, jax, mo, train, ray, docs, d3rlpy)" >&2; exit 2 ;;
  esac
  install "$extra" >"$root/$extra.log" 2>&1 &
  pids+=($!)
done
failed=0
for index in "${!pids[@]}"; do
  if ! wait "${pids[$index]}"; then
    echo "test_extras: installing heartpole[${extras[$index]}] failed:" >&2
    cat "$root/${extras[$index]}.log" >&2
    failed=1
  fi
done
[ "$failed" = 0 ] || exit 1
[ "$setup_only" = 1 ] && exit 0

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for extra in "${extras[@]}"; do
  bin=$root/$extra/bin
  start=$SECONDS
  "$bin/python" -m pip check >/dev/null
  case $extra in
    offline)
      MINARI_DATASETS_PATH=$work/minari "$bin/heartpole" dataset --policy random --episodes 2
      MINARI_DATASETS_PATH=$work/minari "$bin/python" -c '
import minari
dataset = minari.load_dataset("heartpole/v0/random-v0")
env = dataset.recover_environment()
assert env.observation_space == dataset.observation_space
env.reset(seed=0)
env.step(0)'
      MINARI_DATASETS_PATH=$work/minari "$bin/heartpole" ope --dataset heartpole/v0/random-v0 --policy expert \
        --truth-episodes 20
      ;;
    plot) "$bin/heartpole" plot model --out "$work/plots" ;;
    jax)
      "$bin/python" -c '
import jax
import heartpole.jax
env, params = heartpole.jax.make("HeartPole-v0")
obs, state = env.reset(jax.random.key(0), params)
obs, *_ = env.step(jax.random.key(1), state, 2, params)
assert obs.shape == env.observation_space(params).shape'
      ;;
    mo)
      "$bin/python" -c '
import gymnasium as gym, mo_gymnasium, numpy as np
import heartpole
env = mo_gymnasium.wrappers.LinearReward(mo_gymnasium.make("mo-heartpole-v0"), weight=np.float32([1, 100]))
plain = gym.make("HeartPole-v0")
env.reset(seed=0)
plain.reset(seed=0)
for action in [1, 2, 0, 3] * 50:
    _, reward, *_, info = env.step(action)
    assert reward == plain.step(action)[1] and info["vector_reward"].shape == (2,)'
      ;;
    train) "$bin/heartpole" train --timesteps 2000 --n-envs 2 --eval-episodes 10 --out "$work/train" ;;
    ray)
      "$bin/heartpole" train --ray --seeds 0-1 --timesteps 2000 --n-envs 2 --eval-episodes 10 --out "$work/ray"
      ;;
    docs) MKDOCS=$bin/mkdocs bash scripts/build_docs.sh 2>&1 | tail -1 ;;
    d3rlpy) "$bin/python" -m pytest -q -p no:cacheprovider tests/test_clients.py -m slow -k d3rlpy ;;
  esac
  echo "test_extras: heartpole[$extra] alone: its command ran ($((SECONDS - start)) s)"
done
