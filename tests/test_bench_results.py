"""benchmarks/run.py turns the bench scripts' JSON lines into RESULTS.md tables."""
import importlib.util
import sys
from pathlib import Path

spec = importlib.util.spec_from_file_location("bench_run", Path(__file__).resolve().parents[1] / "benchmarks" / "run.py")
bench_run = importlib.util.module_from_spec(spec)
sys.modules["bench_run"] = bench_run  # dataclasses look their module up
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


BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def test_every_target_parses_and_names_a_bench_line_and_figure_its_script_prints():
    targets = bench_run.load_targets()
    assert len({t.id for t in targets}) == len(targets) > 0
    for t in targets:
        source = (BENCHMARKS / f"{t.script}.py").read_text()
        assert f'"bench": "{t.where["bench"]}"' in source, (t.id, t.where["bench"])
        assert f'"{t.figure}"' in source, (t.id, t.figure)
    quick_scripts = {name for name, _, _ in bench_run.QUICK}
    assert {t.script for t in targets if t.quick} <= quick_scripts


def test_a_malformed_target_is_one_line_naming_the_file_and_entry(tmp_path):
    import json
    import pytest
    path = tmp_path / "targets.json"
    path.write_text(json.dumps({"targets": [{"id": "x", "what": "w", "script": "bench_core", "where": {},
                                             "figure": "ms"}]}))
    with pytest.raises(ValueError, match=r"targets.json: target x: .*at_most"):
        bench_run.load_targets(path)


def target(**kw):
    entry = {"id": "t", "what": "solve", "script": "bench_fake", "where": {"bench": "solve"}, "figure": "ms",
             "limit": 2.0, "at_most": True}
    entry.update(kw)
    return bench_run.Target(**entry)


def test_the_worst_matching_record_decides_and_a_dict_figure_is_summed():
    rows = bench_run.records('{"bench": "solve", "ms": 1.5, "nodes": 256}\n{"bench": "solve", "ms": 2.5, "nodes": 512}\n'
                             '{"bench": "net", "lost": {"a": 0, "b": 3}, "bus": "nats"}\n')
    assert bench_run.judge(target(), rows).status == "MISSED"
    assert bench_run.judge(target(), rows).figure == 2.5
    assert bench_run.judge(target(where={"bench": "solve", "nodes": 256}), rows).status == "met"
    assert bench_run.judge(target(unless={"nodes": 512}), rows).status == "met"
    assert bench_run.judge(target(where={"bench": "solve", "nodes": [256, 512]}, at_most=False, limit=1.0),
                           rows).figure == 1.5
    lost = bench_run.judge(target(where={"bench": "net", "bus": "nats"}, figure="lost", limit=0.0), rows)
    assert (lost.figure, lost.status) == (3.0, "MISSED")
    # a field a record lacks is null
    assert bench_run.judge(target(where={"bench": "solve", "threads": None}), rows).records == 2


def test_a_missing_figure_a_failed_script_and_a_script_not_run_are_told_apart():
    rows = bench_run.records('{"bench": "solve", "ms": 1.0}\n{"bench": "solve", "error": "refused"}\n')
    partial = bench_run.judge(target(), rows)
    assert (partial.status, partial.without) == ("MISSED", 1)
    assert bench_run.judge(target(where={"bench": "other"}), rows).status == "NO FIGURE"
    assert bench_run.judge(target(where={"bench": "other"}), [], failed=True).status == "FAILED"
    assert bench_run.judge(target(), None).status == "not run"


def test_results_open_with_the_targets_table():
    outputs = {"bench_fake": '{"bench": "solve", "ms": 1.5}\n'}
    verdicts = bench_run.judge_all([target()], outputs, [], quick=False)
    lines = bench_run.results_markdown(outputs, [], verdicts).splitlines()
    first = lines.index("## Targets")
    assert lines.index("## bench_fake") > first
    row = next(line for line in lines if line.startswith("| solve"))
    assert row.split(" | ")[1:3] == ["1.5", "met"]
