"""Write ``identification.md`` from the identification benchmark's CSV and designs
(``scripts/identification_benchmark.py`` calls it; every number on the page is computed
here from those two files)."""

from __future__ import annotations

import csv
import math
from collections import defaultdict
from pathlib import Path

import numpy as np

LAWS = ("coulomb", "viscous", "stribeck", "exponential")
EXCITATIONS = ("default", "designed")
SNRS = (40.0, 30.0, 20.0)
PERIODS = (10, 20, 50)
PARAMS = {"coulomb": ("lam", "xfk", "xfs"), "viscous": ("lam", "xfk", "xfs", "b1"),
          "stribeck": ("lam", "xfk", "xfs", "b1", "b3"),
          "exponential": ("lam", "xfk", "xfs", "vs", "cv")}


def _pct(x: float) -> str:
    if not math.isfinite(x):
        return "–"
    return f"{100 * x:.2g} %" if abs(x) < 0.1 else f"{100 * x:.0f} %"


def load(path: Path) -> list[dict]:
    with path.open() as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for k in ("snr_db", "truth", "estimate", "se", "ci_lo", "ci_hi", "crlb", "seconds",
                  "cpu_seconds", "residual_ratio", "u0", "nu", "eta", "tanh", "sindy"):
            r[k] = float(r[k]) if r[k] not in ("", "nan") else math.nan
        r["tie"] = tuple(r["tie"].split("|"))
        r["true_sides"] = tuple(int(s) for s in r["true_sides"].split("|") if s)
        r["periods"] = int(r["periods"])
        r["trial"] = int(r["trial"])
        r["flagged"] = r["flagged"] == "True"
        r["converged"] = r["converged"] == "True"
    return rows


def cell_table(rows: list[dict]) -> list[str]:
    by = defaultdict(list)
    for r in rows:
        by[(r["law"], r["excitation"], r["snr_db"], r["periods"], r["param"])].append(r)
    out = []
    for law in LAWS:
        names = PARAMS[law]
        keys = sorted({k[1:4] for k in by if k[0] == law},
                      key=lambda k: (k[0], -k[1], k[2]))
        if not keys:
            continue
        out += [f"### {law}", "",
                "Each parameter: median relative error / Cramér-Rao bound (relative) / "
                "coverage of the 95 % interval.", "",
                "| excitation | SNR | periods | trials | selected | "
                + " | ".join(names) + " |",
                "|---|---|---|---|---|" + "---|" * len(names)]
        for exc, snr, periods in keys:
            cells = []
            first = by[(law, exc, snr, periods, names[0])]
            for n in names:
                rs = by[(law, exc, snr, periods, n)]
                err = np.median([abs(r["estimate"] - r["truth"]) / abs(r["truth"]) for r in rs])
                crlb = rs[0]["crlb"] / abs(rs[0]["truth"])
                cov = np.mean([r["ci_lo"] <= r["truth"] <= r["ci_hi"] for r in rs])
                cells.append(f"{_pct(err)} / {_pct(crlb)} / {100 * cov:.0f} %")
            sel = np.mean([r["best"] == law if not indistinguishable(r)
                           else law in r["tie"] and len(r["tie"]) > 1 for r in first])
            out.append(f"| {exc} | {snr:g} dB | {periods} | {len(first)} | "
                       f"{100 * sel:.0f} % | " + " | ".join(cells) + " |")
        out.append("")
    return out


def indistinguishable(r: dict) -> bool:
    """Whether the record is, by construction, one of two laws at once: a Coulomb or a
    viscous plant whose clean motion slips on one side of the belt speed only once the
    block has first stuck (the viscous term is then linear in v, and a plant of the other
    law makes the same record but for the start's first samples)."""
    return r["law"] in ("coulomb", "viscous") and len(r["true_sides"]) == 1


def records(rows: list[dict]) -> list[dict]:
    """One row per record (its first parameter's)."""
    return [r for r in rows if r["param"] == "lam"]


def selection(rows: list[dict]) -> tuple[list[str], dict]:
    """The selection table per SNR and excitation, and the 30 dB shares (for the targets)."""
    out = ["| SNR | excitation | records that single out a law | correct | "
           "records of two laws at once | tie named, truth among them | one law claimed |",
           "|---|---|---|---|---|---|---|"]
    share: dict = {}
    recs = records(rows)
    for snr in sorted({r["snr_db"] for r in recs}, reverse=True):
        for exc in EXCITATIONS:
            group = [r for r in recs if r["snr_db"] == snr and r["excitation"] == exc]
            if not group:
                continue
            dist = [r for r in group if not indistinguishable(r)]
            twin = [r for r in group if indistinguishable(r)]
            ok = sum(r["best"] == r["law"] for r in dist)
            named = sum(len(r["tie"]) > 1 and r["law"] in r["tie"] for r in twin)
            share[(snr, exc)] = (ok, len(dist), named, len(twin))
            out.append(f"| {snr:g} dB | {exc} | {len(dist)} | "
                       f"{_share(ok, len(dist))} | {len(twin)} | {_share(named, len(twin))} | "
                       f"{sum(len(r['tie']) == 1 for r in twin)} |")
    return out, share


def _share(k: int, n: int) -> str:
    return f"{k} ({100 * k / n:.1f} %)" if n else "–"


def confusion(rows: list[dict]) -> list[str]:
    recs = records(rows)
    out = []
    for snr in sorted({r["snr_db"] for r in recs}, reverse=True):
        counts: dict = defaultdict(int)
        group = [r for r in recs if r["snr_db"] == snr]
        for r in group:
            counts[(r["law"], r["best"] if len(r["tie"]) == 1 else "tie")] += 1
        cols = (*LAWS, "tie")
        out += [f"**{snr:g} dB** ({len(group)} records, all lengths and both excitations; "
                "\"tie\": `identify` named two laws that the record cannot tell apart):", "",
                "| true \\ selected | " + " | ".join(cols) + " |",
                "|---|" + "---|" * len(cols)]
        for law in LAWS:
            out.append(f"| {law} | " + " | ".join(str(counts[(law, s)]) for s in cols) + " |")
        out.append("")
    return out


def projection(rows: list[dict]) -> str:
    """How long the full grid (200 trials per cell) takes on this machine at the measured
    mean cost per record of each (length, excitation), one process."""
    recs = records(rows)
    total, missing = 0.0, []
    for periods in PERIODS:
        for exc in EXCITATIONS:
            secs = [r["seconds"] for r in recs if r["periods"] == periods
                    and r["excitation"] == exc]
            if not secs:
                missing.append(f"{periods} periods {exc}")
                continue
            total += 200 * len(SNRS) * len(LAWS) * float(np.mean(secs))
    text = (f"- The full grid, 200 trials in each of the {len(SNRS) * len(PERIODS) * 2 * len(LAWS)}"
            f" cells (3 SNR × 3 lengths × 2 excitations × 4 laws), would take "
            f"{total / 3600:.0f} hours ({total / 86400:.1f} days) of one process on this "
            "machine, at the mean seconds per record measured for each length and "
            "excitation")
    return text + (f" (no records yet of {', '.join(missing)})." if missing else ".")


def anchors(rows: list[dict]) -> list[str]:
    rs = [r for r in rows if math.isfinite(r["sindy"]) or math.isfinite(r["tanh"])]
    if not rs:
        return ["No anchor trials in the CSV yet."]
    by = defaultdict(list)
    for r in rs:
        by[(r["law"], r["excitation"], r["param"])].append(r)
    out = ["Median signed relative error (bias) of each method on the same records, "
           "30 dB, 20 periods; – where the method has no estimate of that parameter.", "",
           "| law | excitation | trials | parameter | fricenv | tanh + solve_ivp | "
           "SINDy (slip segments) |", "|---|---|---|---|---|---|---|"]
    for (law, exc, name), group in sorted(by.items(), key=lambda kv: (
            LAWS.index(kv[0][0]), kv[0][1], PARAMS[kv[0][0]].index(kv[0][2]))):
        def bias(key: str, group: list[dict] = group) -> str:
            vals = [(r[key] - r["truth"]) / abs(r["truth"]) for r in group
                    if math.isfinite(r[key])]
            return f"{100 * np.median(vals):+.2g} %" if vals else "–"
        out.append(f"| {law} | {exc} | {len(group)} | {name} | {bias('estimate')} | "
                   f"{bias('tanh')} | {bias('sindy')} |")
    return out


def designs_table(designs: dict) -> list[str]:
    out = ["| law | periods | u0 | nu | eta | volume ratio: default | single tone | "
           "random median | stick fraction | reversals | slips above belt |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for key, d in designs.items():
        law, periods = key.split(":")
        s, r, g = d["settings"], d["ratios"], d["regime"]
        out.append(f"| {law} | {periods} | {s['u0']:.3g} | {s['nu']:.3g} | {s['eta']:.3g} | "
                   f"{r['default']:.3g} | {r['single_tone']:.3g} | {r['random_median']:.3g} | "
                   f"{g['stick_fraction']:.2f} | {g['n_reversals']} | "
                   f"{g['slips_above_belt']} |")
    return out


def targets(rows: list[dict], designs: dict) -> list[str]:
    out = []
    # 1: designed excitation, 30 dB, <= 20 periods: bounds <= 1 % on xfs, xfk, lam
    for law in LAWS:
        for periods in (10, 20):
            d = designs.get(f"{law}:{periods}")
            if d is None:
                continue
            worst = max(d["crlb_relative"][n] for n in ("lam", "xfk", "xfs"))
            rs = [r for r in rows if r["law"] == law and r["excitation"] == "designed"
                  and r["snr_db"] == 30.0 and r["periods"] == periods
                  and r["param"] in ("lam", "xfk", "xfs")]
            ratio = "–"
            if rs:
                ratios = []
                for n in ("lam", "xfk", "xfs"):
                    g = [r for r in rs if r["param"] == n]
                    ratios.append(np.median([abs(r["estimate"] - r["truth"]) for r in g])
                                  / g[0]["crlb"])
                ratio = f"{max(ratios):.2f}"
            out.append(f"| {law} | {periods} | {_pct(worst)} | {ratio} |")
    return out


def write_page(out: Path, csv_path: Path, designs: dict, command: str) -> Path:
    rows = load(csv_path)
    counts = defaultdict(set)
    for r in rows:
        counts[(r["snr_db"], r["periods"], r["excitation"])].add((r["law"], r["trial"]))
    recs = records(rows)
    secs = np.array([r["seconds"] for r in recs])
    cpu = np.array([r["cpu_seconds"] for r in recs])
    s20 = np.array([r["seconds"] for r in recs if r["periods"] == 20])
    conv = np.mean([r["converged"] for r in recs])
    sel_table, share = selection(rows)
    d30 = [share.get((30.0, exc), (0, 0, 0, 0)) for exc in EXCITATIONS]
    ok30, n30 = sum(d[0] for d in d30), sum(d[1] for d in d30)
    named30, twin30 = sum(d[2] for d in d30), sum(d[3] for d in d30)
    ratios = np.array([r["residual_ratio"] for r in recs])
    lines = (Path(__file__).with_name("identification_page_head.md").read_text()
             .replace("{command}", command).splitlines())
    lines += ["", "## Trials per cell", "",
              "Trials per (SNR, periods, excitation) cell, each law counted separately "
              "(records in the CSV: "
              f"{len(recs)}):", "", "| SNR | periods | excitation | trials per law |",
              "|---|---|---|---|"]
    for (snr, periods, exc), s in sorted(counts.items(), key=lambda kv: (-kv[0][0], kv[0][1],
                                                                         kv[0][2])):
        per_law = defaultdict(int)
        for law, _ in s:
            per_law[law] += 1
        lines.append(f"| {snr:g} dB | {periods} | {exc} | "
                     + ", ".join(f"{law} {per_law[law]}" for law in LAWS if per_law[law])
                     + " |")
    lines += ["", "## Targets", "",
              "Designed excitation, 30 dB: the largest Cramér-Rao bound of lam, xfk and xfs "
              "(relative, at the truth) and the largest ratio of median absolute error to "
              "that bound among the three:", "",
              "| law | periods | largest bound | median error / bound |", "|---|---|---|---|",
              *targets(rows, designs), "",
              (f"- Correct model selection at 30 dB on the records that single out a law: "
               f"{_share(ok30, n30)} of {n30} (designed excitation "
               f"{_share(d30[1][0], d30[1][1])}, default {_share(d30[0][0], d30[0][1])}); "
               f"on the {twin30} records of two laws at once (Coulomb or viscous records "
               f"that never slip above the belt speed once the block has first stuck), "
               f"`identify` named the tie, the truth among the tied laws, on "
               f"{_share(named30, twin30)}."
               if n30 + twin30 else "- No 30 dB records yet."),
              (f"- Seconds per record, four laws fitted (`identify` alone, anchors excluded; "
               f"one process at a time on the 2-core machine, shared with other jobs, so "
               f"wall time varies with their load; the first record of each process "
               f"includes compiling the kernels; the CSV's earlier records ran before "
               f"`identify` held BLAS to one thread, which made them several times "
               f"slower on this shared machine): median {np.median(secs):.2f}, "
               f"90th percentile {np.percentile(secs, 90):.2f}, largest {secs.max():.2f} "
               f"over all {secs.size} records (CPU seconds: median {np.median(cpu):.2f}, "
               f"largest {cpu.max():.2f}); 20-period records: median "
               f"{np.median(s20):.2f}, largest {s20.max():.2f}." if s20.size else ""),
              projection(rows),
              f"- Fits of the true law that converged: {100 * conv:.1f} %; whose residual "
              f"is within 1.2 times the record's noise level (a model-free estimate, "
              f"`fricenv.identification.model.noise_level`): "
              f"{100 * np.mean(ratios <= 1.2):.1f} %.", "",
              "## Model selection", "",
              "Records that single out a law, and records that are, by construction, "
              "records of two laws at once (a Coulomb or viscous plant whose motion never "
              "slips above the belt speed once the block has first stuck: its record is "
              "also one of the other law):", "",
              *sel_table, "", *confusion(rows),
              "## Designs", "",
              "D-optimal excitation per law and record length at 30 dB, within u0 0.5–5, "
              "nu 0.1–2, eta 0.3–1.2, and how many times larger the confidence ellipsoid "
              "of the law's parameters (lam, xfk, xfs and its own) is under the default "
              "excitation, a single tone of the design's RMS and the median of 20 random "
              "two-tone settings within the bounds (Cramér-Rao volumes at the truth):", "",
              *designs_table(designs), "", "## Error, bound and coverage per cell", "",
              *cell_table(rows), "## Anchors", "", *anchors(rows), ""]
    page = out / "identification.md"
    page.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return page
