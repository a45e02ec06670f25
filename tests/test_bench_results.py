"""benchmarks/run.py turns the bench scripts' JSON lines into RESULTS.md tables."""
import importlib.util
from pathlib import Path

spec = importlib.util.spec_from_file_location("bench_run", Path(__file__).resolve().parents[1] / "benchmarks" / "run.py")
bench_run = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bench_run)


def test_one_table_per_bench_with_every_key_and_no_progress_talk():
    outputs = {
        "bench_fake": 'warming up\n{"bench": "solve", "ms": 1.5}\n{"bench": "solve", "ms": 2.25, "nodes": 512}\n',
        "bench_quiet": "nothing to report\n",
    }
    text = bench_run.results_markdown(outputs, ["bench_quiet.py"])
    lines = text.splitlines()
    fake = lines.index("## bench_fake")
    assert lines[fake + 2:fake + 6] == ["| bench | ms | nodes |", "|---|---|---|",
                                        "| solve | 1.5 |  |", "| solve | 2.25 | 512 |"]
    assert "warming up" not in text
    quiet = lines.index("## bench_quiet")
    assert lines[quiet + 2] == "(no records)"
    assert "Failed: bench_quiet.py" in text


def test_cells_keep_the_table_intact():
    text = bench_run.table([{"a": "x|y", "b": {"k": [1, 2]}}])
    assert text.splitlines()[2] == '| x\\|y | {"k": [1, 2]} |'
