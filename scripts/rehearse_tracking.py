"""Closed-loop recordings (``mjjoint simulate --controller``): tracking and cost per controller.

For each controller (pd, pid) on each side (motor, link) with its default gains, on the
shipped arm with the chapter's sensors (15-bit resolver, 20-bit link encoder, 0.05 N m torque
noise): the rms link tracking error of a slow reference (0.1 rad chirp 0.5 -> 0.2 Hz, 5 s) and
of the lab programme (chirp 30 -> 1 Hz, gravity sweep, steps; 20 s), the largest command, and
the CPU time per simulated second (the controller runs in Python once per sample).

    python scripts/rehearse_tracking.py
"""
from __future__ import annotations

import time

import numpy as np

from mjjoint.excitation import Chirp
from mjjoint.modelfile import ModelFile
from mjjoint.rehearse import Controller, LabProgram, Sensors, run_loop

RATE = 1000.0


def main() -> None:
    model = ModelFile().compile()
    refs = {"slow chirp 0.1 rad": Chirp(amplitude=0.1, f_start=0.5, f_end=0.2).sample(RATE, 5.0),
            "lab programme 20 s": LabProgram(duration=20.0).sample(RATE, 20.0)}
    run_loop(model, refs["slow chirp 0.1 rad"][:10], Controller(), Sensors(), RATE)  # compile the kernels
    print("| controller | side | reference | rms theta error [mrad] | max abs u [N m] | CPU s per simulated s |")
    print("|---|---|---|---|---|---|")
    for on in ("motor", "link"):
        for kind in ("pd", "pid"):
            for name, ref in refs.items():
                start = time.process_time()
                cols = run_loop(model, ref, Controller.default(kind, on), Sensors(), RATE).columns
                cpu = (time.process_time() - start) / (len(ref) / RATE)
                err = 1e3 * np.sqrt(np.mean((ref - cols["theta"]) ** 2))
                print(f"| {kind} | {on} | {name} | {err:.3g} | {np.abs(cols['u']).max():.3g} | {cpu:.3f} |")


if __name__ == "__main__":
    main()
