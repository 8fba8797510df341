"""All of the seed paper's numerical examples (Figs. 2, 4, 6, 8, 9) and lab experiments (Sec. 4)."""
from __future__ import annotations

import argparse
from pathlib import Path

from mjjoint.experiments import (
    friction_lag,
    hysteretic_spring,
    lab,
    linear_joint,
    link_vibration,
    restoring_loops,
)

EXPERIMENTS = (linear_joint, hysteretic_spring, link_vibration, friction_lag, restoring_loops, lab)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/figures"), help="output folder")
    args = parser.parse_args(argv)
    for experiment in EXPERIMENTS:
        for path in experiment.write(args.out):
            print(f"wrote {path}")


if __name__ == "__main__":
    main()
