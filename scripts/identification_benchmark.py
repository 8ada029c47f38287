"""Identification benchmark: error, interval coverage and model selection of
``fricenv.identify`` on simulated records, beside two common practices.

    python scripts/identification_benchmark.py --out docs/results

Records: each law's preset plant (coulomb, viscous, stribeck, exponential) from
x = 0.3, v = 1.4, x sampled every 0.1, white noise at 40, 30 and 20 dB (SNR: the clean x's
variance over the noise's), 10, 20 and 50 periods long (a period is 2 pi / 0.6, the first
tone's at eta = 0.6), under the default excitation (u0 1.5, eta 0.6, nu 0.37) and under the
D-optimal one for that law and length at 30 dB (``fricenv.design_excitation`` within u0
0.5-5, nu 0.1-2, eta 0.3-1.2). Each trial fits all four laws (``identify``'s defaults)
and stores, for the true law, every estimate, standard error and 95 % interval with the
Cramér-Rao bound at the truth; one CSV row per trial (``identification_trials.csv``).
On the 30 dB, 20-period cells, ``--anchor-trials`` trials also run the smoothed-friction
fit on solve_ivp and stick-segmented SINDy (``scripts/identification_anchors.py``; the
``bench`` extra). The page ``identification.md`` is then written from the CSV alone.

The CSV is appended to trial by trial, and a rerun skips the trials already in it: the
default 200 trials per cell may be reached over several runs (``--trials`` sets the
target per cell; ``--cells`` limits a run to some cells, e.g. ``--cells 30:20``).
``--page-only`` rewrites the page from the CSV.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fricenv import OscillatorParams  # noqa: E402
from fricenv.identification import (  # noqa: E402
    DEFAULT_EXCITATION,
    DEFAULT_LAWS,
    LAW_UNKNOWNS,
    design_excitation,
    identify,
    simulate_record,
)
from fricenv.identification.design import fisher_information, marginal_covariance  # noqa: E402
from fricenv.identification.fit import slip_sides  # noqa: E402
from fricenv.identification.model import (  # noqa: E402
    LawModel,
    check_known,
    noise_level,
    start_state,
)
from fricenv.simulate import simulate  # noqa: E402

PERIOD = 2 * math.pi / 0.6
SNRS = (40.0, 30.0, 20.0)
PERIODS = (10, 20, 50)
EXCITATIONS = ("default", "designed")
BOUNDS = {"u0": (0.5, 5.0), "nu": (0.1, 2.0), "eta": (0.3, 1.2)}
START = (0.3, 1.4)
CSV_NAME = "identification_trials.csv"
DESIGNS_NAME = "identification_designs.json"
FIELDS = ["law", "snr_db", "periods", "excitation", "trial", "seed", "best", "tie",
          "true_sides", "converged", "seconds", "cpu_seconds", "residual_ratio", "u0", "nu",
          "eta", "param", "truth", "estimate", "se", "ci_lo", "ci_hi", "crlb", "flagged",
          "tanh", "sindy"]


def names_of(law: str) -> tuple[str, ...]:
    return ("lam", "xfk", "xfs", *LAW_UNKNOWNS[law])


def get_designs(out: Path, laws) -> dict:
    """The D-optimal excitation per law and length, computed once and kept in a JSON."""
    path = out / DESIGNS_NAME
    designs = json.loads(path.read_text()) if path.exists() else {}
    for law in laws:
        for periods in PERIODS:
            key = f"{law}:{periods}"
            if key in designs:
                continue
            t0 = time.perf_counter()
            d = design_excitation(OscillatorParams.preset(law), duration=periods * PERIOD,
                                  bounds=BOUNDS, snr_db=30.0, start=START)
            ratios = d.compare(n_random=20)
            designs[key] = {"settings": d.settings, "crlb_relative": d.crlb_relative,
                            "ratios": ratios, "regime": d.regime,
                            "seconds": time.perf_counter() - t0}
            path.write_text(json.dumps(designs, indent=1))
            print(f"design {key}: {d.settings} ratios {ratios}", flush=True)
    return designs


def crlb_at_truth(p: OscillatorParams, law: str, periods: int, snr: float) -> dict:
    F, _ = fisher_information(p, periods * PERIOD, wrt=names_of(law), snr_db=snr,
                              start=START)
    sd = np.sqrt(np.diag(marginal_covariance(F, len(names_of(law)))))
    return dict(zip(names_of(law), sd.tolist(), strict=True))


def seed_of(law: str, snr: float, periods: int, excitation: str, trial: int) -> int:
    return (DEFAULT_LAWS.index(law) * 1_000_003 + int(snr) * 10_007 + periods * 101
            + EXCITATIONS.index(excitation) * 7 + trial * 7_919_111) % 2**31


def true_sides(p: OscillatorParams, law: str, t: np.ndarray) -> str:
    """The sides of the belt speed on which the clean record slips once the block has
    first stuck ("-1", "1" or "-1|1"; the start's slip before that, from v = 1.4 above
    the belt speed, lasts under one time unit): a Coulomb or viscous record that slips on
    one side only is, but for those first samples, a record of both laws."""
    model = LawModel.make(law, check_known({"eta": p.eta, "nu": p.nu, "u0": p.u0, "V": p.V}))
    values = {n: float(getattr(p, n)) for n in model.names if n not in ("x0", "v0")}
    tr = simulate(p, state=start_state(p, 0.0, *START), t_eval=t)
    ev = tr.events
    first = float(ev["t"][ev["kind"] == 1][0]) if np.any(ev["kind"] == 1) else -math.inf
    return "|".join(str(s) for s in slip_sides(model, values, tr, since=first))


def run_trial(law, snr, periods, excitation, trial, settings, crlb, anchors) -> list[dict]:
    p = OscillatorParams.preset(law, **settings)
    seed = seed_of(law, snr, periods, excitation, trial)
    rec = simulate_record(p, periods * PERIOD, snr_db=snr, rng=np.random.default_rng(seed),
                          start=START)
    known = {"eta": p.eta, "nu": p.nu, "u0": p.u0, "V": p.V}
    t0, c0 = time.perf_counter(), time.process_time()
    res = identify(rec["t"], rec["x"], known=known)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    fit = res.fits[law]
    sides = true_sides(p, law, rec["t"])
    ratio = fit.sigma["x"] / noise_level(rec["t"], rec["x"])
    tanh, sindy = {}, {}
    if anchors:
        from identification_anchors import sindy_fit, tanh_fit

        start = {**{n: float(getattr(OscillatorParams.preset(law), n))
                    for n in ("lam", "xfk", "xfs", *LAW_UNKNOWNS[law])},
                 "x0": fit.estimates["x0"], "v0": fit.estimates["v0"]}
        try:
            tanh = tanh_fit(law, p, rec["t"], rec["x"], start)
        except Exception as e:  # noqa: BLE001 - an anchor's failure is recorded, not fatal
            print(f"tanh fit failed: {e}", flush=True)
        sindy = sindy_fit(law, p, rec["t"], rec["x"])
    rows = []
    for name in names_of(law):
        rows.append({
            "law": law, "snr_db": snr, "periods": periods, "excitation": excitation,
            "trial": trial, "seed": seed, "best": res.best, "tie": "|".join(res.tie),
            "true_sides": sides, "converged": fit.converged, "seconds": round(seconds, 4),
            "cpu_seconds": round(cpu, 4), "residual_ratio": round(ratio, 4),
            "u0": p.u0, "nu": p.nu, "eta": p.eta,
            "param": name, "truth": getattr(p, name), "estimate": fit.estimates[name],
            "se": fit.se[name], "ci_lo": fit.ci[name][0], "ci_hi": fit.ci[name][1],
            "crlb": crlb[name], "flagged": name in fit.undetermined,
            "tanh": tanh.get(name, math.nan), "sindy": sindy.get(name, math.nan)})
    return rows


def done_trials(path: Path) -> set:
    if not path.exists():
        return set()
    with path.open() as f:
        header = next(csv.reader(f), [])
        if header != FIELDS:
            raise SystemExit(f"{path} has the columns {header}, not this benchmark's "
                             f"{FIELDS}: it was written by an earlier version of the fit. "
                             "Move it away to start a new CSV.")
        f.seek(0)
        return {(r["law"], float(r["snr_db"]), int(r["periods"]), r["excitation"],
                 int(r["trial"])) for r in csv.DictReader(f)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out/identification"))
    ap.add_argument("--trials", type=int, default=200, help="trials per cell (target)")
    ap.add_argument("--laws", nargs="+", default=list(DEFAULT_LAWS))
    ap.add_argument("--cells", nargs="+", default=None,
                    help="SNR:PERIODS pairs to run (default: all nine)")
    ap.add_argument("--excitations", nargs="+", default=list(EXCITATIONS))
    ap.add_argument("--anchor-trials", type=int, default=20,
                    help="trials of the 30 dB, 20-period cells that also run the anchors")
    ap.add_argument("--budget-s", type=float, default=math.inf,
                    help="stop starting trials after this many seconds")
    ap.add_argument("--page-only", action="store_true")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / CSV_NAME
    if not args.page_only:
        designs = get_designs(args.out, args.laws)
        cells = ([tuple(float(v) for v in c.split(":")) for c in args.cells] if args.cells
                 else [(s, p) for p in PERIODS for s in SNRS])
        run_grid(args, path, designs, cells)
    from identification_page import write_page

    write_page(args.out, path, json.loads((args.out / DESIGNS_NAME).read_text()),
               " ".join(["python", "scripts/identification_benchmark.py", "--out",
                         str(args.out)]))
    return 0


def run_grid(args, path: Path, designs: dict, cells) -> None:
    done = done_trials(path)
    start = time.perf_counter()
    new_file = not path.exists()
    with path.open("a", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=FIELDS)
        if new_file:
            writer.writeheader()
        # trial-major: every cell gets its first trials before any gets many
        for trial in range(args.trials):
            for snr, periods in cells:
                periods = int(periods)
                for excitation in args.excitations:
                    for law in args.laws:
                        if (law, snr, periods, excitation, trial) in done:
                            continue
                        if time.perf_counter() - start > args.budget_s:
                            print("budget reached", flush=True)
                            return
                        settings = (dict(DEFAULT_EXCITATION) if excitation == "default"
                                    else designs[f"{law}:{periods}"]["settings"])
                        p = OscillatorParams.preset(law, **settings)
                        crlb = crlb_at_truth(p, law, periods, snr)
                        anchors = (snr == 30.0 and periods == 20
                                   and trial < args.anchor_trials)
                        rows = run_trial(law, snr, periods, excitation, trial, settings,
                                         crlb, anchors)
                        writer.writerows(rows)
                        f.flush()
                        os.fsync(f.fileno())
                        print(f"{law} {snr:g} dB {periods} periods {excitation} #{trial}: "
                              f"best {rows[0]['best']}, {rows[0]['seconds']:.2f} s",
                              flush=True)


if __name__ == "__main__":
    raise SystemExit(main())
