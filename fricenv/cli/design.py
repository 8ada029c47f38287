"""``fricenv design``: the two-tone excitation that makes the next record most informative.

Prints the design, its Cramér-Rao bounds and volume ratios against the default excitation,
and writes ``design.png`` (the prior's regime map with the design marked). Example::

    fricenv design --law stribeck --duration 200 --bounds u0=0.5:5,nu=0.1:2,eta=0.3:1.2
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from fricenv.cli._args import add_plant_arguments, number, out_dir, parser, plant


def bound_settings(text: str) -> dict[str, tuple[float, float]]:
    """``u0=0.5:5,nu=0.1:2`` as a dict of (low, high); ``ArgumentTypeError`` naming a bad
    item."""
    out = {}
    for item in text.split(","):
        name, sep, rng = item.partition("=")
        lo, sep2, hi = rng.partition(":")
        try:
            if not (sep and sep2):
                raise ValueError
            out[name.strip()] = (float(lo), float(hi))
        except ValueError:
            raise argparse.ArgumentTypeError(f"{item!r} is not NAME=LOW:HIGH") from None
    return out


def build_parser(prog: str | None = None) -> argparse.ArgumentParser:
    p = parser(prog, "Design the two-tone excitation that maximises the information a "
                     "record gives on a prior plant's friction.",
               ["fricenv design --law stribeck --duration 200 "
                "--bounds u0=0.5:5,nu=0.1:2,eta=0.3:1.2"])
    add_plant_arguments(p, cases=False)
    p.add_argument("--duration", type=number, required=True, help="record length (time)")
    p.add_argument("--bounds", type=bound_settings, required=True,
                   help="forcing settings to choose, NAME=LOW:HIGH, comma-separated")
    p.add_argument("--criterion", default="D", choices=["D", "A", "E"])
    p.add_argument("--snr-db", type=number, default=30.0, help="noise of the record, dB")
    p.add_argument("--no-plot", action="store_true", help="skip design.png (its regime map)")
    p.add_argument("--out", type=out_dir, default=Path("out/design"), help="output folder")
    return p


def main(argv: Sequence[str] | None = None, prog: str | None = None) -> int:
    parser_ = build_parser(prog)
    args = parser_.parse_args(argv)
    from fricenv import plotting
    from fricenv.identification import design_excitation
    from fricenv.identification.report import design_text

    try:
        prior = plant(args)
        design = design_excitation(prior, duration=args.duration, bounds=args.bounds,
                                   criterion=args.criterion, snr_db=args.snr_db)
    except (TypeError, ValueError) as e:
        parser_.error(str(e))
    print(design_text(design))
    ratios = design.compare(n_random=10)
    print("confidence-volume ratio (other / design): " +
          ", ".join(f"{k} {v:.3g}" for k, v in ratios.items()))
    if not args.no_plot:
        args.out.mkdir(parents=True, exist_ok=True)
        png = plotting.save(design.plot(), args.out / "design.png")
        print(f"wrote {png}")
    return 0
