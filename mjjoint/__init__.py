"""mjjoint: elastic robot joints in MuJoCo with 2SEP friction and Bouc-Wen hysteresis, and a
diagnosis that names the physics a model is missing from a recording.

Importing mjjoint registers the ``mjjoint.joint`` engine plugin with MuJoCo, so the shipped
MJCF (``mjjoint.ASSETS_DIR``, package data) loads and runs in plain MuJoCo too::

    import mjjoint, mujoco
    model = mujoco.MjModel.from_xml_path(str(mjjoint.ASSETS_DIR / "arm3.xml"))

Three lines to a simulated recording::

    import mjjoint
    trace = mjjoint.simulate(mjjoint.Chirp().sample(1000, 5))
    trace.to_csv("chirp.csv")

and one call each to fit a model to a recording, or to name what it lacks::

    result = mjjoint.fit("chirp.csv", gear_ratio=160, base=["linear_stiffness", "coulomb_friction"])
    diagnosis = mjjoint.diagnose("chirp.csv", gear_ratio=160, base=["linear_stiffness"])
    print(diagnosis.missing, diagnosis.verdict)
"""
from .assets import ASSETS_DIR, ArmSpec, DriveSpec, build_arm, build_drive, load_model, scene_path
from .coupling.plugin import register, register_model
from .excitation import EXCITATIONS, Chirp, FromFile, Impulse, Multisine, Step
from .joint import GROUND, JointParams, stable_timestep
from .modelfile import ModelFile, dump_model_file, load_model_file
from .physics.boucwen import BoucWen
from .physics.load import LoadFriction
from .physics.ripple import TorqueRipple
from .physics.stribeck import StaticFriction
from .physics.transmission import Transmission
from .physics.twosep import TwoSEP
from .recordings import MultiRecording, Recording, RecordingError, read_recording, write_recording
from .rehearse import Controller, LabProgram, Sensors, run_loop
from .sim import Simulator, Trace, simulate
from .viz import log_traces

# Fitting and diagnosing import scipy.signal and scipy.stats (seconds): their face is loaded on
# first use, so that simulating does not pay for it.
_LAZY = {"fit": "mjjoint.api", "diagnose": "mjjoint.api", "Inputs": "mjjoint.problem",
         "WindowDesign": "mjjoint.identify.windows", "FitResult": "mjjoint.identify.fit",
         "DiagnoseOptions": "mjjoint.diagnosis.loop", "Diagnosis": "mjjoint.diagnosis.loop"}


def __getattr__(name: str):
    import importlib
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    if name == "control":  # imports dm_control and its renderer probe: loaded for those who use it
        return importlib.import_module(".control", __name__)
    raise AttributeError(f"module 'mjjoint' has no attribute {name!r}")


# MuJoCo's parser must know mjjoint.joint before any MJCF that declares it is read, whichever
# API reads it (MjModel.from_xml_path, MjSpec.compile, ...): importing mjjoint is enough.
register()


__version__ = "0.1.0"

__all__ = [
    "ASSETS_DIR", "ArmSpec", "BoucWen", "Controller", "DriveSpec", "Chirp", "DiagnoseOptions", "Diagnosis",
    "EXCITATIONS", "FitResult", "FromFile", "GROUND", "Impulse", "Inputs", "JointParams", "LabProgram",
    "WindowDesign", "diagnose", "fit",
    "LoadFriction", "ModelFile", "MultiRecording", "Multisine", "Recording", "RecordingError",
    "Simulator", "StaticFriction", "Step", "TorqueRipple", "Trace", "Transmission", "TwoSEP",
    "build_arm", "build_drive", "dump_model_file", "load_model", "load_model_file", "log_traces", "read_recording",
    "register", "register_model", "run_loop", "scene_path", "Sensors", "simulate", "stable_timestep", "write_recording",
]
