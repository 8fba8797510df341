"""Fig. 8: static Stribeck map and 2SEP frictional lag under cyclic velocity of increasing frequency."""
from __future__ import annotations

import argparse
from pathlib import Path

from mjjoint.experiments import friction_lag


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/figures"), help="output folder")
    args = parser.parse_args(argv)
    for path in friction_lag.write(args.out):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
