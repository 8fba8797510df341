"""A joint of a moving arm: the other joints' measured motion, carried by MuJoCo, as its load.

``arm``: the arm's multibody model (a ``[[joint]]`` model file or an MJCF with the
``mjjoint.joint`` plugin), checked against a recording. ``load``: the generalised forces the
rest of the arm puts on joint j's dofs, by inverse dynamics of the measured motion.
``predictor``: the single-joint windowed predictor with that load applied every step.
``whole``: joint j simulated inside the whole arm, the other joints made to follow their
measured motion (the route for a ``[[joint]]`` arm: flexible rods are simulated).
"""
from .arm import arm_model
from .load import coupling_load
from .predictor import LoadedPredictor, load_note, loaded_predictor
from .whole import ArmPredictor, arm_predictor

__all__ = ["ArmPredictor", "LoadedPredictor", "arm_predictor", "arm_model", "coupling_load", "load_note", "loaded_predictor"]
