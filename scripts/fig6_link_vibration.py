"""Fig. 6: link vibrations of the joint load (Eq. 10) for two link stiffnesses under a lagged torque step."""
from __future__ import annotations

import argparse
from pathlib import Path

from mjjoint.experiments import link_vibration


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/figures"), help="output folder")
    args = parser.parse_args(argv)
    for path in link_vibration.write(args.out):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
