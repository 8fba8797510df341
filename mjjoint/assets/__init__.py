"""MJCF assets: the shipped arm and direct drive, and builders for their variants."""
from .builder import ASSETS_DIR, ArmSpec, build_arm, load_model, scene_path
from .drive import DriveSpec, build_drive
from .plant import build_plant

__all__ = ["ASSETS_DIR", "ArmSpec", "DriveSpec", "build_arm", "build_drive", "build_plant", "load_model",
           "scene_path"]
