"""The command line every experiment script shares: ``--out DIR``, print what was written."""
from __future__ import annotations

import argparse
from pathlib import Path
from types import ModuleType


def run(experiments: tuple[ModuleType, ...], description: str, argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--out", type=Path, default=Path("out/figures"), help="output folder")
    args = parser.parse_args(argv)
    for experiment in experiments:
        for path in experiment.write(args.out):
            print(f"wrote {path}")
