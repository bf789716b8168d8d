#!/usr/bin/env bash
# Whether this tree's outputs are byte for byte those of another commit:
# profiles and sweeps (--json), maps and poses of every dataset under
# $PIROUETTE_SHARED/datasets and of renders of the built-in scenes, and the
# renders themselves. Builds BASE (default: HEAD) in a worktree under the
# system's temporary folder, then runs both builds on the same inputs.
#
#   PIROUETTE_SHARED=../shared tests/same-outputs.sh [BASE]
#
# BASE_BIN=path/to/pirouette uses that build of BASE instead of building it.
#
# Prints one line per output that differs, and exits 1 if any does.
set -euo pipefail
cd "$(dirname "$0")/.."
base="${1:-HEAD}"
work="$(mktemp -d)"
trap 'git worktree remove --force "$work/base" >/dev/null 2>&1 || true; rm -rf "$work"' EXIT

echo "building this tree and $base (release) ..."
cargo build --release --quiet --bin pirouette
new="$PWD/target/release/pirouette"
if [ -n "${BASE_BIN:-}" ]; then
  old="$BASE_BIN"
else
  git worktree add --quiet --detach "$work/base" "$base"
  (cd "$work/base" && CARGO_TARGET_DIR="$work/base-target" cargo build --release --quiet --bin pirouette)
  old="$work/base-target/release/pirouette"
fi

# What each build writes for one dataset, into $2.
outputs() {
  local bin="$1" data="$2" out="$3"
  mkdir -p "$out"
  "$bin" profile "$data" --json >"$out/profile.json" 2>/dev/null || echo "profile failed" >"$out/profile.json"
  "$bin" sweep "$data" --json >"$out/sweep.json" 2>/dev/null || echo "sweep failed" >"$out/sweep.json"
  "$bin" map "$data" --out "$out/map" >/dev/null 2>&1 || echo "map failed" >"$out/map-failed"
}

datasets=()
if [ -n "${PIROUETTE_SHARED:-}" ] && [ -d "$PIROUETTE_SHARED/datasets" ]; then
  for d in "$PIROUETTE_SHARED"/datasets/*/; do
    [ -f "$d/dataset.json" ] && datasets+=("${d%/}")
  done
else
  echo "PIROUETTE_SHARED unset: only the built-in scenes are compared"
fi
for scene in field-pirouette field-multi room-multi field-multi-b room-multi-b; do
  for which in new old; do
    bin=$new; [ "$which" = old ] && bin=$old
    "$bin" render "$scene" --out "$work/render-$which/$scene" >/dev/null
  done
  datasets+=("render:$scene")
done

differ=0
for d in "${datasets[@]}"; do
  name="$(basename "${d#render:}")"
  if [[ "$d" == render:* ]]; then
    a="$work/render-new/$name"; b="$work/render-old/$name"
    if ! diff -rq "$a" "$b" >/dev/null; then
      echo "differs: render of $name"; differ=1
    fi
    outputs "$new" "$a" "$work/new/$name-render"
    outputs "$old" "$a" "$work/old/$name-render"
    name="$name-render"
  else
    outputs "$new" "$d" "$work/new/$name"
    outputs "$old" "$d" "$work/old/$name"
  fi
  # Timings and peak memory in the summaries vary run to run: not outputs.
  while IFS= read -r f; do
    rel="${f#"$work/new/$name/"}"
    if ! cmp -s "$f" "$work/old/$name/$rel"; then
      echo "differs: $name/$rel"; differ=1
    fi
  done < <(find "$work/new/$name" -type f | sort)
  echo "compared: $name"
done
if [ "$differ" = 0 ]; then
  echo "all outputs identical to $base"
fi
exit "$differ"
