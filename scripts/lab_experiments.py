"""Sec. 4 lab experiments on the simulated arm: impulse FRFs, down-chirp, gravity sweep, step."""
from __future__ import annotations

import argparse
from pathlib import Path

from mjjoint.experiments import lab


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/figures"), help="output folder")
    args = parser.parse_args(argv)
    for path in lab.write(args.out):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
