"""Fig. 9: hysteretic restoring torque on a load-release cycle for mu = 1, 0.5, 0.1."""
from __future__ import annotations

import argparse
from pathlib import Path

from mjjoint.experiments import restoring_loops


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/figures"), help="output folder")
    args = parser.parse_args(argv)
    for path in restoring_loops.write(args.out):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
