"""Where public datasets are looked for: ``$MJJOINT_DATA``, else ``<repo>/../shared/data``.

The datasets are not redistributed with mjjoint (their licences and sizes differ); a checkout
next to a ``shared/data`` folder, or the environment variable, points the readers at them.
"""
from __future__ import annotations

import os
from pathlib import Path

ENV = "MJJOINT_DATA"
# <repo>/mjjoint/datasets/paths.py -> <repo>/../shared/data: the project's development layout.
_DEFAULT = Path(__file__).resolve().parents[2].parent / "shared" / "data"


def data_root() -> Path:
    """The folder holding one sub-folder per dataset (it need not exist)."""
    value = os.environ.get(ENV)
    return Path(value) if value else _DEFAULT


def dataset_dir(name: str) -> Path:
    """``data_root()/name``; a one-line FileNotFoundError saying how to point at it if absent."""
    path = data_root() / name
    if not path.is_dir():
        raise FileNotFoundError(f"dataset folder {path} not found (set {ENV} to the folder that holds {name}/)")
    return path
