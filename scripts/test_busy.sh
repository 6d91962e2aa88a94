#!/usr/bin/env bash
# The default suite (scripts/test.sh) run N times (default 5) while two CPU-burning processes keep both cores
# busy, where the tests' timing margins are tightest (issue 34): one line a run, the failures' names, and exit 1
# if any run failed. Run it as CI runs, e.g. `nohup bash scripts/test_busy.sh 5 > busy.txt`.
set -uo pipefail
cd "$(dirname "$0")/.."
runs="${1:-5}"
bash scripts/setup.sh > /dev/null || exit 1
burners=() log=""
for _ in 1 2; do
  python3 -c 'while True: pass' &
  burners+=("$!")
done
trap 'kill "${burners[@]}" 2> /dev/null; rm -f "$log"' EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
git log --oneline -1
failed=0
for i in $(seq "$runs"); do
  start=$(date +%s)
  log=$(mktemp)
  bash scripts/test.sh > "$log" 2>&1
  code=$?
  echo "run $i: exit $code, $(($(date +%s) - start)) s, load $(cut -d' ' -f1-3 /proc/loadavg): $(tail -1 "$log")"
  if [ "$code" -ne 0 ]; then
    failed=1
    grep -E '^FAILED' "$log"
  fi
  rm -f "$log"
done
exit "$failed"
