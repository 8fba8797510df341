"""Fig. 4: impulse response of a mass on a linear, a hysteretic, and a hysteretic + viscous spring."""
from __future__ import annotations

import argparse
from pathlib import Path

from mjjoint.experiments import hysteretic_spring


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/figures"), help="output folder")
    args = parser.parse_args(argv)
    for path in hysteretic_spring.write(args.out):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
