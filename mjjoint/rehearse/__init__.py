"""Rehearse a recording: the joint in closed loop with the sensors of a real testbed.

A reference (``reference``) is tracked by a saturated PD/PID position loop (``controller``)
closed on quantised, noisy, late angles (``sensors``) around the simulated joint (``loop``);
what the sensors log is a recording ``mjjoint diagnose`` reads as it reads a real one. The
concealed benchmark (``mjjoint.benchmark``) records its truths with it.
"""
from .controller import Controller
from .loop import LoopRun, record, run_loop
from .reference import LabProgram, ReferenceFile
from .sensors import LINK_ENCODER_BITS, RESOLVER_BITS, Sensors, lsb, quantise

__all__ = ["Controller", "LINK_ENCODER_BITS", "LabProgram", "LoopRun", "RESOLVER_BITS", "ReferenceFile",
           "Sensors", "lsb", "quantise", "record", "run_loop"]
