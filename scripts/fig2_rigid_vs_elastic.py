"""Fig. 2: rigid joint (Eq. 2) against elastic joints (Eq. 3, K = 1e3, 1e8): step and amplitude response."""
from __future__ import annotations

import argparse
from pathlib import Path

from mjjoint.experiments import linear_joint


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/figures"), help="output folder")
    args = parser.parse_args(argv)
    for path in linear_joint.write(args.out):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
