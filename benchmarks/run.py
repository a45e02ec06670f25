"""`make bench`: run every benchmarks/bench_*.py (each prints one JSON object per line), check the figures
against benchmarks/targets.json and rewrite benchmarks/RESULTS.md: first one table (target, figure, met or
MISSED), then one table per bench script. Figures are never edited by hand.

`make bench-quick` (`run.py --quick`): the fixed subset in QUICK, well under 90 s on this kind of machine;
it prints the same targets table (only the targets marked "quick") and writes nothing.

The exit status is non-zero when a bench script failed (non-zero exit, timeout) or a target found no record
to read its figure from: a bench that no longer runs is a failure. A MISSED target is reported, not a failure.
The target format is in docs/benchmarks.md.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
TARGETS = HERE / "targets.json"

# the quick subset: (script, arguments, extra environment); each runs at its smallest useful setting
QUICK = (
    ("bench_core", ["--quick", "build_graph:elephant", "solve:256,1024", "skin"], {}),
    ("bench_animate", ["--quick"], {}),
    ("bench_network", ["--captures", "5", "--viewers", "20", "--seconds", "10", "--runs", "embedded"], {}),
)
FULL_TIMEOUT_S = 3 * 3600   # per script: a hang is a failure, not a stuck `make bench`
QUICK_TIMEOUT_S = 300  # a hang guard; the quick run prints its total time


def records(stdout: str) -> list[dict]:
    """The JSON objects among a bench's output lines (other lines are progress talk)."""
    out = []
    for line in stdout.splitlines():
        line = line.strip()
        if line.startswith("{"):
            try:
                value = json.loads(line)
            except ValueError:
                continue
            if isinstance(value, dict):
                out.append(value)
    return out


def cell(value) -> str:
    text = json.dumps(value) if isinstance(value, (dict, list)) else str(value)
    return text.replace("|", "\\|").replace("\n", " ")


def table(rows: list[dict]) -> str:
    """A Markdown table whose columns are every key of the rows, in order of first appearance."""
    columns: list[str] = []
    for row in rows:
        columns += [k for k in row if k not in columns]
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cell(row[k]) if k in row else "" for k in columns) + " |" for row in rows]
    return "\n".join(lines)


@dataclass(frozen=True)
class Target:
    """One entry of targets.json: the records of `script` whose fields equal `where` (and none of `unless`)
    give `figure`; the worst of them must be at most `at_most` or at least `at_least`."""
    id: str
    what: str
    script: str
    where: dict
    figure: str
    limit: float
    at_most: bool
    unit: str = ""
    quick: bool = False
    unless: dict | None = None


def load_targets(path: Path = TARGETS) -> list[Target]:
    """targets.json's entries; a malformed entry is a one-line error naming the file and the entry."""
    entries = json.loads(path.read_text())["targets"]
    out, seen = [], set()
    for i, e in enumerate(entries):
        name = e.get("id", f"#{i}")
        missing = [k for k in ("id", "what", "script", "where", "figure") if k not in e]
        if missing or (("at_most" in e) == ("at_least" in e)):
            raise ValueError(f"{path}: target {name}: needs id, what, script, where, figure and one of at_most, "
                             f"at_least (missing: {', '.join(missing) or 'the limit'})")
        if name in seen:
            raise ValueError(f"{path}: target {name} appears twice")
        seen.add(name)
        known = {"id", "what", "script", "where", "figure", "at_most", "at_least", "unit", "quick", "unless"}
        if set(e) - known:
            raise ValueError(f"{path}: target {name}: unknown keys {sorted(set(e) - known)}")
        out.append(Target(e["id"], e["what"], e["script"], dict(e["where"]), e["figure"],
                          float(e["at_most"] if "at_most" in e else e["at_least"]), "at_most" in e,
                          e.get("unit", ""), bool(e.get("quick", False)), e.get("unless")))
    return out


def _matches(record: dict, fields: dict) -> bool:
    """Every field equals the record's (a list: any of its values); a field the record lacks is null."""
    for key, want in fields.items():
        got = record.get(key)
        if isinstance(want, list) and not isinstance(got, list):
            if got not in want:
                return False
        elif got != want:
            return False
    return True


def figure_of(record: dict, name: str):
    """A record's figure: a number, a dict of numbers summed (e.g. frames lost at each hop), else None."""
    value = record.get(name)
    if isinstance(value, bool):
        return float(value)
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, dict) and value and all(isinstance(v, (int, float)) for v in value.values()):
        return float(sum(value.values()))
    return None


@dataclass(frozen=True)
class Verdict:
    target: Target
    figure: float | None   # the worst matching figure, None when no record gave one
    records: int           # matching records with the figure
    status: str            # "met", "MISSED", "NO FIGURE" (the bench ran, no record matched), "FAILED", "not run"
    without: int = 0       # matching records without the figure (e.g. a clip the command refused): MISSED


def judge(target: Target, rows: list[dict] | None, failed: bool = False) -> Verdict:
    """The target against a script's records (None: the script was not run)."""
    if rows is None:
        return Verdict(target, None, 0, "not run")
    picked = [r for r in rows if _matches(r, target.where) and not (target.unless and _matches(r, target.unless))]
    values = [figure_of(r, target.figure) for r in picked]
    found = [v for v in values if v is not None]
    if not found:
        return Verdict(target, None, 0, "FAILED" if failed else "NO FIGURE", len(values))
    worst = max(found) if target.at_most else min(found)
    met = (worst <= target.limit if target.at_most else worst >= target.limit) and len(found) == len(values)
    return Verdict(target, worst, len(found), "met" if met else "MISSED", len(values) - len(found))


def number(x: float) -> str:
    return f"{x:.3g}" if abs(x) < 1000 else f"{x:.0f}"


def targets_table(verdicts: list[Verdict]) -> str:
    lines = ["| target | figure | met? | bench |", "|---|---|---|---|"]
    for v in verdicts:
        t = v.target
        limit = f"{'≤' if t.at_most else '≥'} {number(t.limit)}{(' ' + t.unit) if t.unit else ''}"
        fig = "–" if v.figure is None else number(v.figure) + (f" {t.unit}" if t.unit else "")
        if v.records > 1:
            fig += f" (worst of {v.records})"
        if v.without:
            fig += f"; {v.without} record{'s' * (v.without > 1)} without it"
        where = ", ".join(f"{k}={w if isinstance(w, str) else json.dumps(w)}" for k, w in t.where.items())
        lines.append(f"| {cell(t.what)} {limit} | {fig} | {v.status} | {t.script}: {cell(where)} |")
    return "\n".join(lines)


def judge_all(targets: list[Target], outputs: dict[str, str], failed: list[str], quick: bool) -> list[Verdict]:
    parsed = {name: records(stdout) for name, stdout in outputs.items()}
    chosen = [t for t in targets if t.quick or not quick]
    return [judge(t, parsed.get(t.script), f"{t.script}.py" in failed) for t in chosen]


def results_markdown(outputs: dict[str, str], failed: list[str] = (), verdicts: list[Verdict] = ()) -> str:
    """RESULTS.md from each bench script's name and captured stdout, the targets table first."""
    parts = ["# Benchmark results", "",
             "Written by `make bench` (benchmarks/run.py) from the JSON lines each bench prints; do not edit.", ""]
    if verdicts:
        parts += ["## Targets", "", "From benchmarks/targets.json; a figure is the worst of the records the target "
                  "names (docs/benchmarks.md).", "", targets_table(verdicts), ""]
    if failed:
        parts += ["Failed: " + ", ".join(failed), ""]
    for name, stdout in outputs.items():
        parts += [f"## {name}", ""]
        rows = records(stdout)
        parts += [table(rows) if rows else "(no records)", ""]
    return "\n".join(parts)


def run_script(name: str, args: list[str], env: dict, timeout: float) -> tuple[str, int | str]:
    """(stdout, exit status or "timeout") of one bench script; its JSON lines are echoed as they come."""
    print(f"# {name} {' '.join(args)}".rstrip(), file=sys.stderr, flush=True)
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, str(HERE / f"{name}.py"), *args], stdout=subprocess.PIPE, text=True,
                            env={**os.environ, **env})
    try:
        stdout, _ = proc.communicate(timeout=timeout)
        status: int | str = proc.returncode
    except subprocess.TimeoutExpired:
        proc.kill()
        stdout, _ = proc.communicate()
        status = "timeout"
    sys.stdout.write(stdout)
    sys.stdout.flush()
    print(f"# {name}: {time.monotonic() - t0:.0f} s, status {status}", file=sys.stderr, flush=True)
    return stdout, status


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the fixed quick subset; print the targets table only")
    args = ap.parse_args(argv)
    targets = load_targets()
    outputs: dict[str, str] = {}
    failed: list[str] = []
    t0 = time.monotonic()
    # the full run also makes the quick tier's small studio run, so its targets have a figure in RESULTS.md too
    plan = QUICK if args.quick else [(p.stem, [], {}) for p in sorted(HERE.glob("bench_*.py"))] + \
        [step for step in QUICK if step[0] == "bench_network"]
    for name, script_args, env in plan:
        stdout, status = run_script(name, script_args, env, QUICK_TIMEOUT_S if args.quick else FULL_TIMEOUT_S)
        outputs[name] = outputs.get(name, "") + stdout
        if status != 0:
            failed.append(f"{name}.py" + (" (timeout)" if status == "timeout" else f" (exit {status})"))
    failed_scripts = [f.split(" ")[0] for f in failed]
    verdicts = judge_all(targets, outputs, failed_scripts, args.quick)
    if args.quick:
        print(f"\n## Targets (make bench-quick, {time.monotonic() - t0:.0f} s)\n\n{targets_table(verdicts)}\n")
    else:
        (HERE / "RESULTS.md").write_text(results_markdown(outputs, failed, verdicts))
        print(f"\n## Targets\n\n{targets_table(verdicts)}\n")
    missing = [v.target.id for v in verdicts if v.status in ("NO FIGURE", "FAILED")]
    problems = (["failed: " + ", ".join(failed)] if failed else []) + \
        (["no figure for: " + ", ".join(missing)] if missing else [])
    if problems:
        print("benchmarks " + "; ".join(problems), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
