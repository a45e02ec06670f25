"""`make bench`: run every benchmarks/bench_*.py (each prints one JSON object per line) and rewrite
benchmarks/RESULTS.md from what they printed, one table per bench script. Figures are never edited by hand."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


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


def results_markdown(outputs: dict[str, str], failed: list[str] = ()) -> str:
    """RESULTS.md from each bench script's name and captured stdout."""
    parts = ["# Benchmark results", "",
             "Written by `make bench` (benchmarks/run.py) from the JSON lines each bench prints; do not edit.", ""]
    for name, stdout in outputs.items():
        parts += [f"## {name}", ""]
        rows = records(stdout)
        parts += [table(rows) if rows else "(no records)", ""]
    if failed:
        parts += ["Failed: " + ", ".join(failed), ""]
    return "\n".join(parts)


def main() -> None:
    outputs: dict[str, str] = {}
    failed = []
    for script in sorted(HERE.glob("bench_*.py")):
        print(f"# {script.name}", file=sys.stderr, flush=True)
        run = subprocess.run([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
        sys.stdout.write(run.stdout)
        sys.stdout.flush()
        outputs[script.stem] = run.stdout
        if run.returncode != 0:
            failed.append(script.name)
    (HERE / "RESULTS.md").write_text(results_markdown(outputs, failed))
    if failed:
        sys.exit(f"benchmarks failed: {', '.join(failed)}")


if __name__ == "__main__":
    main()
