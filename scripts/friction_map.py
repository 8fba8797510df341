"""Friction-map mode on generated friction logs: which effects it names and what it recovers.

Each log is 8 s at 1 kHz of a prescribed motion (0.8 sin(2 pi 0.25 t) + 0.3 sin(2 pi 1.1 t) rad)
with the friction torque of the simulator's own friction kernels plus 0.02 N m of noise. Prints
the table of docs/diagnosis.md ("Friction-map mode"): `python scripts/friction_map.py`.
"""
from __future__ import annotations

import time

import numpy as np

from mjjoint.identify.friction_map import FrictionLog, fit_friction_map, friction_term, friction_trace
from mjjoint.identify.windows import velocity

RATE, NOISE = 1000.0, 0.02
STATIC = {"coulomb_friction.fc": 2.0, "viscous_friction.sigma": 0.5}
STRIBECK = {**STATIC, "stribeck_friction.ratio": 1.6, "stribeck_friction.vs": 0.2}
CASES = {
    "Coulomb + viscous": (("coulomb_friction", "viscous_friction"), STATIC),
    "+ Stribeck": (("coulomb_friction", "viscous_friction", "stribeck_friction"), STRIBECK),
    "+ Stribeck + 2SEP (K 200, B 500)": (
        ("coulomb_friction", "viscous_friction", "stribeck_friction", "dynamic_friction"),
        {**STRIBECK, "dynamic_friction.k": 200.0, "dynamic_friction.b": 500.0}),
}


def log(effects, values) -> FrictionLog:
    t = np.arange(0.0, 8.0, 1.0 / RATE)
    q = 0.8 * np.sin(2 * np.pi * 0.25 * t) + 0.3 * np.sin(2 * np.pi * 1.1 * t)
    tau = friction_trace(friction_term(effects, values, 1e-7), velocity(q, 1.0 / RATE), 1.0 / RATE)
    return FrictionLog(((t, q, tau + np.random.default_rng(0).normal(0.0, NOISE, len(t))),))


def main() -> None:
    print("| truth | named | RMS before -> after [N m] | largest parameter error | s |")
    print("|---|---|---|---|---|")
    for name, (effects, values) in CASES.items():
        start = time.perf_counter()
        result = fit_friction_map(log(effects, values))
        seconds = time.perf_counter() - start
        got = result.final.values
        errors = {k: abs(got[k] / v - 1) for k, v in values.items() if k in got}
        worst = max(errors, key=errors.get)
        named = ", ".join(s["effect"] for s in result.steps) or "nothing"
        print(f"| {name} | {named} | {result.base.rms:.3f} -> {result.final.rms:.3f} | "
              f"{worst} {100 * errors[worst]:.1f} % | {seconds:.1f} |")


if __name__ == "__main__":
    main()
