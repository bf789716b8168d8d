#!/usr/bin/env bash
# GTSAM (PyPI `gtsam`, Levenberg-Marquardt with default settings) beside
# `pirouette graph optimise` on the same g2o files, in one run.
#
#   benches/graph_peer.sh [G2O_FILE ...]
#
# Without files: intel.g2o and manhattan.g2o from $PIROUETTE_SHARED/posegraph
# (or ../shared/posegraph). Installs GTSAM into benches/.venv (git-ignored)
# on first use; skips with a message where PyPI cannot be reached.
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${RUNS:-5}
if [ $# -eq 0 ]; then
  shared=${PIROUETTE_SHARED:-../shared}
  set -- "$shared/posegraph/intel.g2o" "$shared/posegraph/manhattan.g2o"
fi
for f in "$@"; do
  [ -f "$f" ] || { echo "skipped: $f not found (set PIROUETTE_SHARED)"; exit 0; }
done
venv=benches/.venv
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import gtsam' 2>/dev/null; then
  echo "installing GTSAM from PyPI into $venv ..."
  if ! { python3 -m venv "$venv" && "$venv/bin/pip" install -q gtsam numpy; }; then
    echo "skipped: GTSAM could not be installed (is PyPI reachable?)"
    exit 0
  fi
fi
cargo build --release --quiet
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs); $(date -u +%Y-%m-%d)"
echo "medians of $runs runs; chi² diff = (pirouette − GTSAM) / GTSAM, both scored with g2o's eᵀΩe"
"$venv/bin/python" benches/graph_peer.py target/release/pirouette "$runs" "$@"
