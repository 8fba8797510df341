"""An independently written plant of the seed's joint, and out-of-regime cases built on it.

Nothing in mjjoint's core imports this package, and it imports nothing of mjjoint's simulator:
its recordings test the diagnosis against physics it was not written with (docs/benchmark.md,
"Out-of-regime set").
"""
from .friction import LuGre, MaxwellSlip, PositionDependence, TwoSEP
from .gear import BoucWenLaw, StopHysteresis
from .plant import Cogging, JointPlant, Rod, simulate
from .record import Excitation, Sensors, record, write_csv

__all__ = ["BoucWenLaw", "Cogging", "Excitation", "JointPlant", "LuGre", "MaxwellSlip", "StopHysteresis",
           "PositionDependence", "Rod", "Sensors", "TwoSEP", "record", "simulate", "write_csv"]
