"""A joint of a moving arm: the other joints' measured motion, carried by MuJoCo, as its load.

``arm``: the arm's multibody model (a ``[[joint]]`` model file or an MJCF with the
``mjjoint.joint`` plugin), checked against a recording. ``load``: the generalised forces the
rest of the arm puts on joint j's dofs, by inverse dynamics of the measured motion.
``predictor``: the single-joint windowed predictor with that load applied every step.
"""
from .arm import arm_model
from .load import coupling_load
from .predictor import LoadedPredictor, load_note, loaded_predictor

__all__ = ["LoadedPredictor", "arm_model", "coupling_load", "load_note", "loaded_predictor"]
