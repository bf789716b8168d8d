#!/usr/bin/env bash
# Maps a simulated CARMEN laser log of about SIZE megabytes (default 1000)
# and reports its peak resident memory, time and accuracy. The log (a
# robot wandering a 4 × 4 block office floor with a 270° scanner of 1,081
# beams, see examples/office_log.rs) is made in a temporary folder and
# removed afterwards; nothing is committed.
#
#   benches/big-log.sh [SIZE_MB]
#
# Needs /usr/bin/time (GNU time) for the peak memory; about 45 minutes
# for 1000 MB on a 2-core machine.
set -euo pipefail
size="${1:-1000}"
cd "$(dirname "$0")/.."
if [[ ! -x /usr/bin/time ]]; then
    echo "big-log: /usr/bin/time (GNU time) not found; skipped" >&2
    exit 0
fi
cargo build --release --quiet --bin pirouette --example office_log
work="$(mktemp -d "${TMPDIR:-/tmp}/big-log.XXXXXX")"
trap 'rm -rf "$work"' EXIT
target/release/examples/office_log --megabytes "$size" "$work/office.log"
ls -l "$work/office.log"
/usr/bin/time -v target/release/pirouette map "$work/office.log" --out "$work/map" 2>"$work/time.txt"
grep -E "Maximum resident set size|Elapsed \(wall clock\)" "$work/time.txt"
target/release/pirouette eval laser "$work/office.log" "$work/map"
