"""Sensor noise and delay in returns as well as in retained stick cut, from the
benchmark's per-episode CSV (no compute).

    python -m fricenv_agents.noise_report [--csv docs/results/control_benchmark_episodes.csv]
        [--out out/noise-report]

A retention (a condition's stick cut over the in-range one) can look high while the
return falls, and a controller's retention against its own in-range cut hides how far
that cut is below another controller's. So per scene and controller run under noise and
delay this reports, with paired 95 % intervals over the shared plants:

- the IQM return in range and under noise + delay, and the change between them,
  ``(noisy - in range) / |in range|`` (negative: worse under noise; for the filtered
  MPC, which runs under noise only, against the bound MPC in range);
- the stick cut under noise + delay over the controller's own in-range cut (the
  benchmark's retention), and over the nominal PPO's in-range cut.

The in-range and noise + delay conditions draw the same plants (the same plant seeds), so
the two are paired. Writes ``noise_report.md`` and ``noise_report.json`` to ``--out``.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from . import statistics as S
from .benchmark_records import cell_of, read_episodes, write_report
from .benchmark_rows import CUT_AGGREGATE
from .cli import HelpFormatter

NOISY = "noise + delay"
IN_RANGE = "in range"
REFERENCE = "ppo"  #: whose in-range cut the second retention divides by
BOOT_SEED = 0


def _iv(i: S.Interval) -> dict[str, float]:
    return {"estimate": i.estimate, "lo": i.lo, "hi": i.hi}


def scene_report(rows: list[dict[str, Any]], scene: str, key: str) -> dict[str, Any]:
    """The statistics the module docstring lists for controller ``key`` on ``scene``.
    A controller with several runs is paired run by run with its own in-range cells; the
    robust PPO's five runs and the nominal PPO's five are resampled with the same row
    indices (independent runs: this pairs nothing but keeps one draw per replicate)."""
    base = key if (scene, IN_RANGE, key) in {(r["scene"], r["condition"], r["controller"])
                                             for r in rows} else "mpc"
    ret_in, ret_noisy = cell_of(rows, scene, IN_RANGE, base), cell_of(rows, scene, NOISY, key)
    st_in = cell_of(rows, scene, IN_RANGE, base, "stick_fraction")
    st_noisy = cell_of(rows, scene, NOISY, key, "stick_fraction")
    z_in = cell_of(rows, scene, IN_RANGE, "zero", "stick_fraction")
    z_noisy = cell_of(rows, scene, NOISY, "zero", "stick_fraction")
    ref_in = cell_of(rows, scene, IN_RANGE, REFERENCE, "stick_fraction")
    strata = len({r["eval_seed"] for r in rows if r["scene"] == scene
                  and r["condition"] == NOISY and r["controller"] == "zero"})
    agg, cut_agg = S.cell_stat(S.iqm), S.cell_stat(CUT_AGGREGATE)

    def cut(c: Any, z: Any) -> Any:
        return 1.0 - cut_agg(c) / cut_agg(z)

    out: dict[str, Any] = {"in_range_of": base}
    out["return_in_range"] = _iv(S.iqm_ci(ret_in, strata, seed=BOOT_SEED))
    out["return_noisy"] = _iv(S.iqm_ci(ret_noisy, strata, seed=BOOT_SEED))
    out["return_change"] = _iv(S.paired_ci(lambda a, b: (agg(b) - agg(a)) / abs(agg(a)),
                                           [ret_in, ret_noisy], strata, seed=BOOT_SEED))
    out["retention_own"] = _iv(S.paired_ci(lambda c, z, ci, zi: cut(c, z) / cut(ci, zi),
                                           [st_noisy, z_noisy, st_in, z_in], strata,
                                           seed=BOOT_SEED))
    out["retention_of_ppo"] = _iv(S.paired_ci(lambda c, z, ci, zi: cut(c, z) / cut(ci, zi),
                                              [st_noisy, z_noisy, ref_in, z_in], strata,
                                              seed=BOOT_SEED))
    return out


def report(rows: list[dict[str, Any]]) -> dict[str, dict[str, dict[str, Any]]]:
    """scene -> controller -> ``scene_report``, for every controller run under noise."""
    out: dict[str, dict[str, dict[str, Any]]] = {}
    for scene in sorted({r["scene"] for r in rows if r["condition"] == NOISY}):
        keys = sorted({r["controller"] for r in rows if r["scene"] == scene
                       and r["condition"] == NOISY} - {"zero"})
        out[scene] = {k: scene_report(rows, scene, k) for k in keys}
    return out


def markdown(rep: dict[str, dict[str, dict[str, Any]]]) -> str:
    def f(d: dict[str, float] | None, digits: int = 2, scale: float = 1.0,
          suffix: str = "", signed: bool = False) -> str:
        if d is None:
            return "—"
        return S.Interval(d["estimate"], d["lo"], d["hi"]).format(digits, scale, suffix,
                                                                  signed)

    lines = ["# Noise and delay: returns and retained cut", "",
             "Made by `python -m fricenv_agents.noise_report` from the benchmark's "
             "[per-episode CSV](control_benchmark_episodes.csv) (see its docstring). Return: "
             "IQM [95 % CI]; change: (noise + delay − in range) / |in range|, paired over the "
             "same plants. Retention: the stick cut under noise + delay over an in-range "
             "cut, its own (for the filtered MPC: the bound MPC's) or the nominal PPO's. The "
             "MPC, bound and filtered, plans with the settings `MPPIController(scene)` "
             "had when the benchmark ran (each scene's tuned ones since 2026-11-28, "
             "[the search](mpc_tuning.md)).", "",
             "| scene | controller | return, in range | return, noise + delay | change | "
             "retention of its own cut | retention of the nominal PPO's cut |",
             "|---|---|---:|---:|---:|---:|---:|"]
    for scene, per in rep.items():
        for key, r in per.items():
            lines.append(f"| `{scene}` | {key} | {f(r['return_in_range'])} | "
                         f"{f(r['return_noisy'])} | "
                         f"{f(r['return_change'], 1, 100, ' %', True)} | "
                         f"{f(r['retention_own'], 1, 100, ' %')} | "
                         f"{f(r.get('retention_of_ppo'), 1, 100, ' %')} |")
    return "\n".join([*lines, ""])


def main(argv: Sequence[str] | None = None) -> Path:
    from .mpc_compare import DEFAULT_CSV

    p = argparse.ArgumentParser(prog="python -m fricenv_agents.noise_report",
                                description=__doc__.split("\n\n")[0],
                                formatter_class=HelpFormatter)
    p.add_argument("--csv", type=Path, default=DEFAULT_CSV)
    p.add_argument("--out", type=Path, default=Path("out/noise-report"))
    args = p.parse_args(argv)
    rep = report(read_episodes(args.csv))
    args.out.mkdir(parents=True, exist_ok=True)
    return write_report(args.out, "noise_report", rep, markdown(rep))


if __name__ == "__main__":
    main()
