"""fricenv.bench.compile: argument checks, the pairing of numba's compile events and
their self times, the tables, and real child processes on a warm cache."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fricenv.bench import compile as bc

ROOT = Path(__file__).resolve().parents[1]


def _fake_tree(path: Path, init: str = "") -> Path:
    (path / "fricenv").mkdir(parents=True)
    (path / "fricenv" / "__init__.py").write_text(init)
    return path


# -- arguments ------------------------------------------------------------------------------
@pytest.mark.parametrize(("argv", "needle"), [
    (["--tree", "{tmp}/empty"], "argument --tree: '{tmp}/empty' is not a checkout"),
    (["--tree", "{root}", "--tree", "{root}"], "argument --tree: the same tree twice"),
    (["--tree", "{root}", "--tree", "{tmp}/t1", "--tree", "{tmp}/t2"],
     "argument --tree: at most two trees (old, new), got 3"),
    (["--workloads", "run_stats", "nosuch"], "argument --workloads: invalid choice: 'nosuch'"),
    (["--repeat", "0"], "argument --repeat: must be a whole number >= 1, got '0'"),
    (["--repeat", "two"], "argument --repeat: must be a whole number >= 1, got 'two'"),
    (["--timeout", "-1"], "argument --timeout: must be a finite number > 0, got '-1'"),
    (["--cache-dir", "{tmp}/afile"], "argument --cache-dir: {tmp}/afile is a file"),
    (["--cache-dir", "{tmp}/c", "--inherit-cache"],
     "argument --inherit-cache: not allowed with argument --cache-dir"),
    (["--json", "{tmp}"], "argument --json: '{tmp}' is a folder, not a file"),
    (["--json", "{tmp}/no/r.json"],
     "argument --json: the folder of '{tmp}/no/r.json' does not exist"),
])
def test_bad_arguments_are_refused_by_name(argv, needle, tmp_path, capsys) -> None:
    """Exit 2 with a message naming the option and the value, before any child runs or
    anything is written."""
    (tmp_path / "empty").mkdir()
    (tmp_path / "afile").write_text("")
    _fake_tree(tmp_path / "t1")
    _fake_tree(tmp_path / "t2")
    before = sorted(p.name for p in tmp_path.iterdir())
    sub = {"tmp": str(tmp_path), "root": str(ROOT)}
    with pytest.raises(SystemExit) as e:
        bc.main([a.format(**sub) for a in argv])
    assert e.value.code == 2
    assert needle.format(**sub) in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_help_lists_every_workload(capsys) -> None:
    with pytest.raises(SystemExit) as e:
        bc.parse_args(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    for name in bc.WORKLOADS:
        assert f"  {name} " in out


def test_defaults_and_workload_order(tmp_path) -> None:
    args = bc.parse_args([])
    assert args.tree == [ROOT]
    assert args.workloads == list(bc.WORKLOADS)
    assert args.repeat == 1 and args.cache_dir is None and not args.inherit_cache
    args = bc.parse_args(["--workloads", "mpc", "atlas", "mpc", "--cache-dir",
                          str(tmp_path / "c")])
    assert args.workloads == ["mpc", "atlas"]
    assert args.cache_dir == (tmp_path / "c").resolve()
    assert not (tmp_path / "c").exists()  # made only when the children start


def test_workloads_follow_the_package() -> None:
    """The workload names are fixed in the script (for --help); they must name every scene,
    method and friction law the package has."""
    import fricenv
    from fricenv.envs import ENV_IDS
    from fricenv.layout import METHODS

    assert sorted(bc.SCENES) == sorted(ENV_IDS.values())
    assert bc.SIMULATE_METHODS == tuple(METHODS)
    assert set(bc.MAP_LAWS) <= set(fricenv.FRICTION_LAWS)
    assert list(bc.RUNNERS) == list(bc.WORKLOADS)


# -- compile events --------------------------------------------------------------------------
def _ev(t: float, kind: str, name: str, sig: str = "(float64,)", phase: str = "first"):
    return {"t": t, "kind": kind, "name": name, "sig": sig, "phase": phase}


NESTED = [_ev(0, "start", "A"), _ev(1, "start", "B"), _ev(1.5, "start", "C"),
          _ev(2, "end", "C"), _ev(4, "end", "B"), _ev(5, "start", "D"), _ev(6, "end", "D"),
          _ev(10, "end", "A"), _ev(11, "start", "E", phase="warm"),
          _ev(11.25, "end", "E", phase="warm")]


def test_pairing_gives_inclusive_and_self_time() -> None:
    cs = bc.pair_compiles(NESTED)
    assert [c.name for c in cs] == ["A", "B", "C", "D", "E"]  # in the order they started
    assert [c.inclusive for c in cs] == [10, 3, 0.5, 1, 0.25]
    # self: less the compilations directly inside (A: B and D; B: C), not their insides
    assert [c.self_time for c in cs] == [6, 2.5, 0.5, 1, 0.25]
    assert [c.depth for c in cs] == [0, 1, 2, 1, 0]
    assert [c.phase for c in cs] == ["first"] * 4 + ["warm"]
    assert sum(c.self_time for c in cs) == 10.25  # self times partition the outer spans
    assert bc.compile_summary(cs) == (5, 10.25)
    assert bc.compile_summary(c for c in cs if c.phase != "warm") == (4, 10)
    assert bc.pair_compiles([]) == []


def test_recursive_compilation_counts_its_span_once() -> None:
    events = [_ev(0, "start", "A"), _ev(1, "start", "A", "(int64,)"),
              _ev(2, "end", "A", "(int64,)"), _ev(3, "end", "A")]
    cs = bc.pair_compiles(events)
    assert [c.outermost for c in cs] == [True, False]
    (a,) = bc.kernel_totals({"w": cs})
    assert (a.self_s, a.inclusive_s, a.compiles) == (3, 3, 2)


@pytest.mark.parametrize(("events", "needle"), [
    ([_ev(0, "end", "A")], "END of A (float64,) with no START open"),
    ([_ev(0, "start", "A"), _ev(1, "end", "B")], "END of B (float64,) inside the "
                                                 "compilation of A"),
    ([_ev(0, "start", "A"), _ev(1, "end", "A", "(int64,)")], "inside the compilation"),
    ([_ev(0, "start", "A"), _ev(1, "start", "B"), _ev(2, "end", "B")],
     "START of A (float64,) never ended"),
    ([{**_ev(0, "start", "A"), "kind": "begin"}], "kind must be 'start' or 'end'"),
])
def test_unpaired_events_are_refused(events, needle) -> None:
    with pytest.raises(ValueError) as e:
        bc.pair_compiles(events)
    assert needle in str(e.value)


def test_kernel_totals_pool_workloads_and_repeats() -> None:
    cs = bc.pair_compiles(NESTED[:8])
    again = bc.pair_compiles([_ev(0, "start", "B"), _ev(2, "end", "B")])
    totals = bc.kernel_totals({"w1": cs, "w2": again}, runs=2)
    assert [k.name for k in totals] == ["A", "B", "D", "C"]  # self time, largest first
    a, b = totals[0], totals[1]
    assert (a.self_s, a.inclusive_s, a.compiles, a.workloads) == (3, 5, 0.5, {"w1"})
    assert (b.self_s, b.inclusive_s, b.compiles, b.workloads) == (2.25, 2.5, 1, {"w1", "w2"})
    with pytest.raises(ValueError, match="runs must be >= 1, got 0"):
        bc.kernel_totals({}, runs=0)


# -- tables ----------------------------------------------------------------------------------
def _metrics(scale: float) -> dict[str, float]:
    return {"import_s": 1.0 * scale, "first_s": 20.0 * scale, "cpu_s": 19.5 * scale,
            "rss_mb": 300.0 * scale, "warm_ms": 0.5 * scale, "compiles": 40 * scale,
            "compile_s": 18.0 * scale}


def test_results_table_one_tree() -> None:
    text = bc.results_table({"run_stats": {"tree": _metrics(1)}, "mpc": {"tree": None}},
                            ["tree"])
    lines = text.splitlines()
    assert lines[0] == ("| workload | import s | first call s | CPU s | peak RSS MB | warm ms "
                        "| compiles | compile s |")
    assert lines[1] == "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"
    assert lines[2] == "| run_stats | 1.00 | 20.00 | 19.50 | 300 | 0.50 | 40 | 18.00 |"
    assert lines[3] == "| mpc" + " | failed" * 7 + " |"


def test_results_table_two_trees_gives_new_over_old() -> None:
    old, new = _metrics(1), _metrics(0.5)
    new["compiles"] = 0
    text = bc.results_table({"atlas": {"old": old, "new": new},
                             "mpc": {"old": {**old, "compiles": 0}, "new": None}},
                            ["old", "new"])
    header, _, atlas, mpc = (line.split(" | ") for line in text.splitlines())
    assert header[1:4] == ["import s (old)", "import s (new)", "import s new/old"]
    assert len(header) == 1 + 3 * len(bc.METRICS)
    assert atlas[1:4] == ["1.00", "0.50", "0.50"]
    assert atlas[16:19] == ["40", "0", "0.00"]  # compiles: old, new, ratio
    assert mpc[1:4] == ["1.00", "failed", "–"]


def test_top_table_lists_ten_largest_by_self_time() -> None:
    events = []
    for i in range(12):
        events += [_ev(10 * i, "start", f"k{i:02d}"), _ev(10 * i + i + 1, "end", f"k{i:02d}")]
    text = bc.top_table(bc.kernel_totals({"w": bc.pair_compiles(events)}))
    lines = text.splitlines()
    assert lines[0] == "| # | kernel | self s | inclusive s | compiles | workloads |"
    assert len(lines) == 2 + 10
    assert lines[2] == "| 1 | `k11` | 12.00 | 12.00 | 1 | 1 |"
    assert lines[-1].startswith("| 10 | `k02` |")


# -- real children -----------------------------------------------------------------------------
def test_a_failed_child_is_reported_with_its_stderr(tmp_path, capsys) -> None:
    tree = _fake_tree(tmp_path / "broken", "raise RuntimeError('this tree does not import')")
    assert bc.main(["--tree", str(tree), "--workloads", "run_stats"]) == 1
    out = capsys.readouterr().out
    assert "| run_stats | failed |" in out
    assert f"FAILED: run_stats (tree, {tree})" in out
    assert "RuntimeError: this tree does not import" in out


def test_child_on_a_warm_cache_compiles_nothing(tmp_path, capsys) -> None:
    """The cheapest workload in a real child, on the numba cache this process uses, warmed
    here first: every kernel loads from the cache, so the child compiles nothing."""
    import fricenv

    tree = Path(fricenv.__file__).resolve().parents[1]  # the tree this process imports
    bc.RUNNERS["run_stats"](tmp_path)  # compiles into the cache at most once, here
    out_json = tmp_path / "r.json"
    assert bc.main(["--tree", str(tree), "--workloads", "run_stats", "--inherit-cache",
                    "--json", str(out_json)]) == 0
    assert "| run_stats |" in capsys.readouterr().out
    (run,) = json.loads(out_json.read_text())["runs"]
    assert not run["failed"]
    assert Path(run["fricenv"]).is_relative_to(tree)
    assert run["compiles"] == 0 and run["warm_compiles"] == 0 and run["events"] == []
    assert run["first_s"] > 0 and run["warm_ms"] > 0 and run["cpu_s"] > 0
    assert 10 < run["rss_mb"] < 10_000
    assert 0 < run["import_s"] < 120


@pytest.mark.slow
def test_a_shared_cache_dir_compiles_only_the_first_time(tmp_path) -> None:
    """Cold, then again on the same --cache-dir: the second run compiles nothing."""
    cache, out_json = tmp_path / "cache", tmp_path / "r.json"
    assert bc.main(["--workloads", "run_stats", "--repeat", "2", "--cache-dir", str(cache),
                    "--json", str(out_json)]) == 0
    first, second = json.loads(out_json.read_text())["runs"]
    assert first["compiles"] > 0 and first["compile_s"] > 0
    assert second["compiles"] == 0
    names = {e["name"] for e in first["events"]}
    assert any(n.startswith("fricenv.") for n in names)


def test_registered_as_fricenv_bench_compile(capsys) -> None:
    from fricenv.cli.bench import main

    assert main(["compile", "--help"], prog="fricenv bench") == 0
    out = capsys.readouterr().out
    assert "usage: " in out and "--workloads NAME" in out
    assert "--cache-dir DIR" in out and "  map-stribeck " in out
    assert main(["compile", "--repeat", "0"], prog="fricenv bench") == 2
    assert "argument --repeat" in capsys.readouterr().err
