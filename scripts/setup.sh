#!/usr/bin/env bash
# Create .venv (once) with HeartPole and all its extras. PyTorch comes first, pinned to the local CPU
# build (torch==2.13.0), so that stable-baselines3 does not pull the multi-GB CUDA build.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -x .venv/bin/python ]; then
  python3 -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip
.venv/bin/python -m pip install -q torch==2.13.0
.venv/bin/python -m pip install -q -e ".[all]"
