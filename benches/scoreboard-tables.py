#!/usr/bin/env python3
"""BENCHMARKS.md's scoreboard tables, written from one scoreboard.json.

    benches/scoreboard-tables.py OUT/scoreboard.json              # print them
    benches/scoreboard-tables.py OUT/scoreboard.json BENCHMARKS.md  # replace them there

`pirouette eval suite --out OUT` writes OUT/scoreboard.json. The tables
go between the lines `<!-- scoreboard-tables: begin -->` and
`<!-- scoreboard-tables: end -->` of the Markdown file, which is written
whole to a temporary file and renamed over the old one. Every figure
comes from the one run the file records (its commit, processor, day and
command are the tables' first line), so that the board is regenerated,
never edited by hand. Standard library only.
"""

import json
import os
import sys
import tempfile

BEGIN = "<!-- scoreboard-tables: begin -->"
END = "<!-- scoreboard-tables: end -->"

# Figures shown as percentages.
PERCENT = {"missed", "false_range", "wrong_unmarked_share", "profile_agreement"}
# Figures that count things.
COUNTS = {"wrong_verified", "far_wrong", "relations_unmatched", "answers", "iterations"}
# Names for people.
NAMES = {
    "missed": "profile bins missed",
    "false_range": "free bins given a range",
    "wrong_verified": "verified turns > 3° off",
    "ate_aligned_m": "ATE aligned",
    "f1": "map F1",
    "precision": "precision",
    "far_wrong": "far queries answered wrong",
    "pose_error_max_deg": "largest heading error",
    "rpe_1m_m": "RPE 1 m",
    "rpe_1m_vs_odometry": "RPE 1 m over the log's with odometry",
    "relations_trans_vs_cartographer": "relations, translation over Cartographer's",
    "relations_rot_vs_cartographer": "relations, rotation over Cartographer's",
    "relations_unmatched": "relations unmatched",
    "time_vs_cartographer": "time over Cartographer's published",
    "chi2_vs_reference": "χ² over the reference",
    "inlier_chi2_vs_reference": "outliers: χ² of the true edges over the reference",
    "heading_rmse_deg": "heading RMSE",
    "turn_error_median_deg": "turn error median",
    "turn_error_p95_deg": "turn error p95",
    "heading_after_full_turn_deg": "heading after a full turn",
    "profile_agreement": "profile agreement",
    "time_s": "time",
    "peak_mb": "peak memory",
}


def num(v, figure=""):
    """A figure with about three significant digits, in its unit."""
    if v is None:
        return "missing"
    if figure in COUNTS and v == int(v):
        return f"{int(v)}"
    if figure in PERCENT:
        return f"{100 * v:.2f} %"
    if figure == "time_s":
        if v < 1:
            return f"{1000 * v:.0f} ms"
        return f"{v:.1f} s" if v < 600 else f"{v / 60:.1f} min"
    if figure == "peak_mb":
        return f"{v:.0f} MB"
    if figure.endswith("_m") and figure != "relations_unmatched":
        return f"{100 * v:.2f} cm" if abs(v) < 1 else f"{v:.2f} m"
    if figure.endswith("_deg"):
        return f"{v:.2f}°"
    if v == 0 or v != v:
        return f"{v:g}"
    if abs(v) >= 100:
        return f"{v:.0f}"
    return f"{v:#.3g}" if abs(v) >= 1 else f"{v:.3f}"


def bound(text, figure):
    """A target or gate (`≤ 0.02`, `≥ 0.9`, `0.1-0.2`) in its figure's unit."""
    for sign in ("≤ ", "≥ "):
        if text.startswith(sign):
            return sign + num(float(text[len(sign):]), figure)
    lo, dash, hi = text.partition("-")
    if dash and lo and hi:
        return f"{num(float(lo), figure)} to {num(float(hi), figure)}"
    return text


def short(error, n=100):
    """A failure's reason, cut to `n` characters."""
    reason = error.rsplit("error: ", 1)[-1]
    return reason if len(reason) <= n else reason[: n - 1] + "…"


def minutes(s):
    m, s = divmod(round(s), 60)
    return f"{m} min {s} s" if m else f"{s} s"


def summary(board):
    out = [
        "| kind | cases | figure | target (gate) | worst (case) | median | short |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for kind, s in board["summary"].items():
        first = True
        # Targeted figures first, then time and memory.
        figures = sorted(s["figures"].items(), key=lambda kv: kv[0] in ("time_s", "peak_mb"))
        for name, f in figures:
            gate = f.get("gate")
            target = bound(f["target"], name)
            if gate:
                target += " (gated)" if gate == f["target"] else f" (gate {bound(gate, name)})"
            worst = num(f["worst"], name)
            if f["worst_case"]:
                worst += f" ({f['worst_case']})"
            cells = [kind if first else "", str(s["cases"]) if first else ""]
            cells += [NAMES.get(name, name), target, worst, num(f["median"], name)]
            cells.append(str(len(f["misses"])) if f["target"] != "-" else "")
            out.append("| " + " | ".join(cells) + " |")
            first = False
        if s["failed"]:
            out.append(f"| | | failed to run | | {len(s['failed'])} (below) | | |")
    return out


def cases(board, title, pick, columns):
    """A table of the rows `pick` keeps, one column per (figure, heading)."""
    rows = [r for r in board["rows"] if pick(r["case"])]
    if not rows:
        return []
    out = ["", f"{title}:", "", "| case | " + " | ".join(h for _, h in columns) + " | short of target |"]
    out.append("| --- |" + " --- |" * (len(columns) + 1))
    for r in sorted(rows, key=lambda r: r["case"]):
        cells = [r["case"]]
        if r.get("error"):
            cells += [""] * len(columns) + [f"failed: {short(r['error'])}"]
        else:
            missed = {m["figure"] for m in r["misses"]}
            cells += [num(r["figures"][f], f) if f in r["figures"]
                      else "missing" if f in missed else "-" for f, _ in columns]
            cells.append(", ".join(m["figure"] for m in r["misses"]) or "-")
        out.append("| " + " | ".join(cells) + " |")
    return out


def command(recorded):
    """The recorded command line, run as a checkout's release build (the
    board may have run a copy of it, so that a rebuild did not touch it)."""
    words = recorded.split()
    if words and os.path.basename(words[0]).startswith("pirouette"):
        words[0] = "target/release/pirouette"
    return " ".join(words)


def tables(board):
    p = board["provenance"]
    runs = board["rows"]
    kinds = ", ".join(f"{s['cases']} {k}" for k, s in board["summary"].items())
    out = [
        BEGIN,
        f"Commit `{p['commit']}`, {p['cpu']} ({p['cores']} cores), {p['date']}: "
        f"{len(runs)} cases ({kinds}), {board['jobs']} at once, "
        f"{minutes(p['wall_s'])}; time is the least of {board['repeats']} run(s). "
        "Written by `benches/scoreboard-tables.py` from that run's scoreboard.json.",
        "",
        "```sh",
        f"PIROUETTE_SHARED=$PWD/../shared {command(p['command'])}",
        f"benches/scoreboard-tables.py OUT/scoreboard.json BENCHMARKS.md",
        "```",
        "",
    ]
    out += summary(board)
    shared_camera = {"field-multi", "field-multi-b", "field-open", "field-pirouette",
                     "office-multi", "office-multi-b"}
    out += cases(board, "The shared camera sets", lambda c: c in shared_camera, [
        ("missed", "bins missed"), ("false_range", "free bins given a range"),
        ("wrong_verified", "turns > 3° off"), ("ate_aligned_m", "ATE aligned"),
        ("f1", "F1"), ("time_s", "time"), ("peak_mb", "peak memory")])
    out += cases(board, "Real recordings (against motion capture, on its clock as found from "
                 "the images)", lambda c: c.startswith("tum-") or " every " in c, [
        ("ate_aligned_m", "ATE aligned"), ("heading_rmse_deg", "heading RMSE"),
        ("turn_error_median_deg", "turn error median"), ("turn_error_p95_deg", "turn error p95"),
        ("heading_after_full_turn_deg", "heading after a full turn"),
        ("profile_agreement", "profile agreement"), ("time_s", "time"),
        ("peak_mb", "peak memory")])
    out += cases(board, "Places of the shared sets (index / queries)",
                 lambda c: " / " in c and "seed" not in c, [
        ("answers", "answers"), ("precision", "precision"), ("recall_at_1", "recall@1"),
        ("far_wrong", "far queries answered wrong"), ("pose_error_max_deg", "largest heading error"),
        ("pose_error_max_m", "largest position error"), ("time_s", "time")])
    out += cases(board, "Laser logs as recorded (against each log's recorded trajectory)",
                 lambda c: c.endswith(":as-recorded"), [
        ("rpe_1m_m", "RPE 1 m"), ("rpe_1m_deg", "RPE 1 m, rotation"), ("ate_m", "ATE"),
        ("wrong_unmarked_share", "steps wrong, unmarked"), ("time_s", "time"),
        ("peak_mb", "peak memory")])
    out += cases(board, "The benchmark's bags (relations; Cartographer's figures as published, "
                 "its time on other hardware)", lambda c: c.endswith(".bag"), [
        ("relations_trans_m", "translation"), ("relations_rot_deg", "rotation"),
        ("relations_trans_vs_cartographer", "over Cartographer's"),
        ("relations_rot_vs_cartographer", "over Cartographer's, rotation"),
        ("relations_unmatched", "unmatched"), ("time_s", "time"),
        ("time_vs_cartographer", "over Cartographer's time"), ("peak_mb", "peak memory")])
    out += cases(board, "Pose graphs", lambda c: ":" in c and not c.split(":")[1].startswith(
        ("as-recorded", "no-odometry", "every", "noisy")), [
        ("chi2_vs_reference", "χ² over the reference"),
        ("inlier_chi2_vs_reference", "true edges' χ² over the reference"),
        ("iterations", "iterations"), ("time_s", "time")])
    by_figure = {}
    for r in runs:
        for g in r.get("gate_failures", []):
            by_figure[g] = by_figure.get(g, 0) + 1
    total = sum(by_figure.values())
    listed = ", ".join(f"{NAMES.get(g, g)} {n}" for g, n in sorted(by_figure.items()))
    out += ["", f"Gated targets failed (`eval suite --check` fails on them; the cases are in "
            f"scoreboard.md): {total}" + (f" ({listed})." if total else ".")]
    out.append(END)
    return "\n".join(out) + "\n"


def main(argv):
    if len(argv) not in (2, 3):
        sys.exit(__doc__.strip().split("\n\n")[1])
    try:
        with open(argv[1], encoding="utf-8") as f:
            board = json.load(f)
        text = tables(board)
    except (OSError, ValueError, KeyError, TypeError) as e:
        sys.exit(f"{argv[1]}: not a scoreboard.json of this build ({type(e).__name__}: {e})")
    if len(argv) == 2:
        sys.stdout.write(text)
        return
    md = argv[2]
    with open(md, encoding="utf-8") as f:
        old = f.read()
    if old.count(BEGIN) != 1 or old.count(END) != 1 or old.index(BEGIN) > old.index(END):
        sys.exit(f"{md}: needs one `{BEGIN}` line and one `{END}` line after it")
    new = old[: old.index(BEGIN)] + text + old[old.index(END) + len(END) + 1:]
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(os.path.abspath(md)), prefix=".benchmarks-")
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(new)
    os.replace(tmp, md)


if __name__ == "__main__":
    main(sys.argv)
