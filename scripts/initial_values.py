"""Scale-free identification: the recording's own initial values, and the fits from them.

For a small servo motor and a large robot-axis motor (mjjoint.experiments.servo, 6 s at 1 kHz,
noise-free), the truth, the estimate ``identify.initial.estimate`` gives, and the fit of
Coulomb + viscous friction from it (as ``mjjoint fit --plant rotary``: 0.5 s windows, 15 LM
iterations, 2 restarts); then the arm's gear stiffness from the torque sensor and, without it,
from the resonance. Prints a markdown table (docs/diagnosis.md).

    python scripts/initial_values.py
"""
from __future__ import annotations

from mjjoint.problem import drive_structure
from mjjoint.experiments.servo import LARGE, SMALL, geared_recording, servo_recording
from mjjoint.identify.fit import fit
from mjjoint.identify.initial import estimate
from mjjoint.identify.windows import Measured, Predictor, WindowDesign


def main() -> None:
    print("| plant | parameter | truth | estimate | fit | fit error |")
    print("|---|---|---|---|---|---|")
    for label, servo in (("small servo", SMALL), ("large axis", LARGE)):
        measured = Measured.from_recording(servo_recording(servo), 1.0, output=False)
        base = drive_structure(("coulomb_friction", "viscous_friction"), "hinge", measured)
        res = fit(Predictor(measured, WindowDesign(length=0.5)), base, max_iter=15, restarts=2)
        for name, truth in (("inertia.motor", servo.inertia), ("coulomb_friction.fc", servo.coulomb),
                            ("viscous_friction.sigma", servo.viscous)):
            got = res.structure.values[name]
            print(f"| {label} | {name} | {truth:.4g} | {base.start.values[name]:.4g} | {got:.4g} | "
                  f"{100 * (got / truth - 1):+.1f} % |")
    for k1 in (3e3, 3e4):
        measured, arm = geared_recording(k1)
        with_tau = estimate(measured, arm).values["linear_stiffness.k1"]
        measured.tau = None
        e = estimate(measured, arm)
        print(f"| arm, tau measured | linear_stiffness.k1 | {k1:.4g} | {with_tau:.4g} | | |")
        print(f"| arm, no tau ({e.resonance:.1f} Hz) | linear_stiffness.k1 | {k1:.4g} | "
              f"{e.values['linear_stiffness.k1']:.4g} | | |")


if __name__ == "__main__":
    main()
