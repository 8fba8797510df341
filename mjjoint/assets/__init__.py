"""MJCF assets: the shipped arm and a builder for its variants."""
from .builder import ASSETS_DIR, ArmSpec, build_arm, load_model, scene_path

__all__ = ["ASSETS_DIR", "ArmSpec", "build_arm", "load_model", "scene_path"]
