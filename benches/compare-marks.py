#!/usr/bin/env python3
"""Compares the trust marks of two maps of one laser log, scan by scan.

    benches/compare-marks.py BASE_MAP_DIR NEW_MAP_DIR [...]

Each argument pair names two `pirouette map` output folders of the same log
(say, one made by an older build and one by this one). For the scans both
registered, it prints how many carry the same mark in `poses.json`
("ambiguous", "unmatched" or none) and lists those that differ.
"""

import json
import sys


def marks(folder):
    with open(f"{folder}/poses.json", encoding="utf-8") as f:
        return {p["scan"]: p.get("trust") for p in json.load(f)}


def main(argv):
    if len(argv) < 2 or len(argv) % 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    worst = 100.0
    for base_dir, new_dir in zip(argv[0::2], argv[1::2]):
        try:
            base, new = marks(base_dir), marks(new_dir)
        except (OSError, ValueError, KeyError) as e:
            print(f"error: {e}", file=sys.stderr)
            return 1
        both = sorted(set(base) & set(new))
        if not both:
            print(f"error: {base_dir} and {new_dir} share no registered scan", file=sys.stderr)
            return 1
        differ = [k for k in both if base[k] != new[k]]
        share = 100.0 * (len(both) - len(differ)) / len(both)
        worst = min(worst, share)
        print(
            f"{new_dir}: {len(both)} scans registered by both, {share:.2f} % with the same mark "
            f"(marked: {sum(1 for v in base.values() if v)} before, {sum(1 for v in new.values() if v)} now)"
        )
        for k in differ:
            print(f"  scan {k}: {base[k] or 'trusted'} before, {new[k] or 'trusted'} now")
    print(f"worst: {worst:.2f} % of scans with the same mark")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
