"""The throughput measurement: its result's structure, rates and env share, the Markdown
tables, the command line and its refusals. No timing is asserted beyond being positive and
finite: the machine may be shared."""

from __future__ import annotations

import json
import math

import pytest

pytest.importorskip("stable_baselines3", reason="the agents need the rl extra")

from fricenv_agents import throughput as TP  # noqa: E402


@pytest.fixture(scope="module")
def result() -> dict:
    """Two tiny plant counts on one scene, two rounds, and one PPO rollout (SB3 rounds the
    256 steps up to one rollout of n_steps x n_envs)."""
    return TP.measure(["paper"], [1, 3], ppo_steps=256, rounds=2)


def _positive(x: float) -> bool:
    return math.isfinite(x) and x > 0.0


def test_result_holds_the_machine_and_a_row_per_plant_count(result):
    assert set(result) == {"machine", "vector", "ppo", "seconds"}
    m = result["machine"]
    assert m["cpu_count"] >= 1 and m["numba_threads"] >= 1 and m["torch_threads"] == 1
    assert m["numba_threading_layer"] in ("tbb", "omp", "workqueue")
    assert {"fricenv", "numpy", "numba", "torch", "stable_baselines3"} <= set(m["versions"])
    assert len(m["load_average_1min"]) == 2
    assert [(r["scene"], r["plants"]) for r in result["vector"]] == [("paper", 1), ("paper", 3)]
    assert json.loads(json.dumps(result)) == result  # JSON-able, as it is


def test_vector_rates_are_positive_and_the_median_lies_in_the_spread(result):
    for r in result["vector"]:
        assert r["rounds"] == 2 and r["steps_per_round"] >= 3
        assert all(_positive(r[k]) for k in ("plant_steps_per_s", "slowest_round",
                                             "fastest_round", "step_us"))
        assert r["slowest_round"] <= r["plant_steps_per_s"] <= r["fastest_round"]
        # plants / seconds per step, both medians of the same rounds
        assert r["plant_steps_per_s"] == pytest.approx(r["plants"] / (r["step_us"] * 1e-6))
        assert r["plant_steps_per_s"] > 100.0  # generous: a step of one plant under 10 ms


def test_ppo_row_has_its_rate_and_an_env_share_between_0_and_1(result):
    (r,) = result["ppo"]
    assert r["scene"] == "paper" and r["n_envs"] == 16 and r["normalize"] is True
    assert r["timesteps"] == r["n_steps"] * r["n_envs"] and r["rollouts"] == 1
    assert _positive(r["samples_per_s"]) and _positive(r["env_samples_per_s"])
    assert 0.0 < r["env_share"] < 1.0
    assert r["env_s"] == pytest.approx(r["env_share"] * r["wall_s"])
    assert r["samples_per_s"] == pytest.approx(r["timesteps"] / r["wall_s"])


def test_markdown_has_a_table_row_per_measurement(result):
    lines = TP.markdown(result)
    assert lines[0] == "### Throughput"
    rows = [line for line in lines if line.startswith("| paper |")]
    assert len(rows) == 3  # two plant counts and PPO
    assert rows[0].startswith("| paper | 1 | ") and rows[2].startswith("| paper | 16 | ")
    assert " % | " in rows[2]
    machine_line = lines[2]
    assert result["machine"]["numba_threading_layer"] in machine_line


def test_no_ppo_with_zero_steps():
    r = TP.measure(["paper"], [2], ppo_steps=0, rounds=1)
    assert r["ppo"] == [] and len(r["vector"]) == 1
    assert not any("samples/s" in line for line in TP.markdown(r))


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"scenes": ["nope"]}, "unknown scene 'nope'"),
    ({"scenes": "paper"}, "scenes must be a non-empty sequence"),
    ({"scenes": ["paper", "paper"]}, "must not repeat"),
    ({"plants": []}, "plants must be a non-empty sequence"),
    ({"plants": [0]}, "plants must be an integer >= 1"),
    ({"plants": [2, 2]}, r"must not repeat a count, got \[2, 2\]"),
    ({"ppo_steps": -1}, "ppo_steps must be an integer >= 0"),
    ({"rounds": 0}, "rounds must be an integer >= 1"),
])
def test_bad_arguments_are_refused_before_any_work(kwargs, match):
    with pytest.raises(ValueError, match=match):
        TP.measure(**{"scenes": ["paper"], "plants": [1], **kwargs})


def test_command_line_writes_json_and_markdown(tmp_path, capsys):
    out = tmp_path / "out"
    result = TP.main(["--scenes", "paper", "--plants", "2", "--ppo-steps", "0", "--rounds",
                      "1", "--out", str(out), "--quiet"])
    assert json.loads((out / "throughput.json").read_text()) == result
    md = (out / "throughput.md").read_text()
    assert md.startswith("### Throughput") and "| paper | 2 | " in md
    assert "| paper | 2 | " in capsys.readouterr().out


def test_command_line_refuses_a_bad_plant_count(capsys):
    with pytest.raises(SystemExit) as e:
        TP.main(["--plants", "0", "--quiet"])
    assert e.value.code == 2
    assert "plants must be an integer >= 1, got 0" in capsys.readouterr().err
