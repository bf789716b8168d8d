#!/usr/bin/env bash
# Runs every fuzz target for a given time (or a given number of
# executions) and reports executions and crashes per target.
#
#   fuzz/run.sh [SECONDS] [RUNS]        defaults: 600 seconds, 1000000 runs
#
# Needs a nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz`).
# Crashing inputs land in fuzz/artifacts/TARGET/; copy them into
# tests/fuzz-regressions/TARGET/ so that the ordinary test suite runs them.
set -uo pipefail
cd "$(dirname "$0")"
seconds=${1:-600}
runs=${2:-1000000}
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
  echo "skipped: cargo-fuzz on a nightly toolchain is needed (rustup toolchain install nightly; cargo install cargo-fuzz)"
  exit 0
fi
cargo +nightly fuzz build -O >/dev/null 2>&1 || { echo "the fuzz targets do not build"; exit 1; }
printf '%-10s %12s %10s %8s\n' target executions seconds crashes
status=0
for target in $(cargo +nightly fuzz list); do
  mkdir -p "corpus/$target"
  log=$(mktemp)
  cargo +nightly fuzz run -O "$target" "corpus/$target" -- \
    -max_total_time="$seconds" -runs="$runs" -rss_limit_mb=2048 -print_final_stats=1 >"$log" 2>&1
  code=$?
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -1)
  took=$(grep -o 'Done [0-9]* runs in [0-9]* second' "$log" | grep -o 'in [0-9]*' | grep -o '[0-9]*' | tail -1)
  crashes=$(ls "artifacts/$target" 2>/dev/null | wc -l)
  printf '%-10s %12s %10s %8s\n' "$target" "${execs:-?}" "${took:-?}" "$crashes"
  if [ "$code" -ne 0 ]; then
    status=1
    grep -m3 -E 'panicked|ERROR|SUMMARY' "$log" | sed 's/^/    /'
  fi
  rm -f "$log"
done
exit $status
