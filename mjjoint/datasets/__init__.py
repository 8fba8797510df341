"""Readers of public measured datasets, each in mjjoint's conventions (see docs/datasets.md).

The data are never part of this package: ``paths.data_root()`` says where they are looked for.
"""
