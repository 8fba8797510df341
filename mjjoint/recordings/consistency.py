"""Whether a recording's signals are read on the sides and with the signs the model takes.

A recording that breaks a convention fits without complaint to a model that cannot be right,
so it is refused with what it looks like and the remedy:

* angles: q is the motor angle before the gear, theta the link angle after it, so wherever the
  link follows the motor q moves about N times theta (q read after the gear, the two swapped,
  one encoder's sign flipped, another gear ratio break it);
* the sign of u: the rotor's power balance, (u - tau/N) w = d/dt(J w^2/2) + F w with friction
  taking work out, so over a recording the torque left on the rotor does work on it; a flipped
  u makes it give work back instead;
* the sign of tau: the gear is a spring (play and hysteresis included), so tau rises with the
  deflection q/N - theta; a flipped tau falls with it.

Before any of these, the motor must move: a recording of a joint at rest holds nothing to fit.
"""
from __future__ import annotations

import numpy as np

# The link follows the motor when the two angles correlate at least this well; below it (an
# output held still, a gear whose play or compliance dominates the motion) there is nothing to
# compare.
FOLLOWS = 0.9
# q per theta within this factor of the gear ratio either way is a gear read on its two sides
# (the deflection moves it by a small fraction).
RATIO_FACTOR = 2.0


# The rotor gives back more than this share of the work the torques on it exchange: a sign is
# flipped (friction alone makes the mean power positive; the kinetic energy's change over the
# recording is a small share of what a driven rotor exchanges).
GIVES_BACK = 0.2
# tau against the deflection: a spring's correlation is near +1 (0.84-1.0 over the benchmark
# recordings, play and hysteresis included); this far below zero it is a flipped sign.
SPRING_SIGN = -0.5
# The motor moves when q spans more than this many of its smallest steps (encoder counts).
MOVES = 10


# What a sensor that never changes while the motor moves means, and what to do about it.
_DEAD = {
    "tau": "the torque sensor recorded nothing (leave the tau column out)",
    "theta": ("the link encoder recorded nothing (without one, fit the motor alone: --plant rotary with theta "
              "mapped to q's column), or the output was held, which fit and diagnose do not model"),
}


def dead_sensor_problem(signal: str, x: np.ndarray) -> str | None:
    """What is wrong where ``signal`` (tau or theta) never changes while the motor moves (the gear
    carries the link's inertia torque, the link follows through it), else None."""
    if np.ptp(x) > 0:
        return None
    return f"{signal} is {float(x[0]):g} throughout while the motor moves: {_DEAD[signal]}"


# [rad, m, N m, A, ...] below every encoder's count and every drive's command: a recording whose
# angle or input never reaches it was written in another unit than the one read
TINY = 1e-9


def scale_problem(signal: str, x: np.ndarray) -> str | None:
    """What is wrong where ``signal`` never reaches TINY in magnitude but is not zero, else None."""
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    if not 0 < peak < TINY:
        return None
    return (f"{signal} never exceeds {peak:.3g} in magnitude, below any sensor's or drive's resolution: "
            f"check its unit (--scales {signal}=FACTOR)")


def motion_problem(q: np.ndarray) -> str | None:
    """What is wrong where the motor angle does not move beyond a few encoder counts, else None."""
    span = float(np.ptp(q))
    steps = np.abs(np.diff(q))
    steps = steps[steps > 1e-9 * span]  # above the rounding of arithmetic on the angles
    if steps.size and span > MOVES * float(steps.min()):
        return None
    return (f"the motor angle q spans {span:.3g} rad, {'no' if not steps.size else 'under ' + str(MOVES)} "
            "encoder steps: a joint at rest holds nothing to fit (drive it, or check the q column)")


def gear_sides_problem(q: np.ndarray, theta: np.ndarray, gear_ratio: float) -> str | None:
    """A one-line account of what the angles look like where q does not move about ``gear_ratio``
    times theta, with the remedy; None where they agree or cannot be compared."""
    dq, dth = q - np.mean(q), theta - np.mean(theta)
    sq, sth = float(np.sqrt(dq @ dq)), float(np.sqrt(dth @ dth))
    if not (sq > 0 and sth > 0):
        return None
    r = float(dq @ dth) / (sq * sth)
    if abs(r) < FOLLOWS:
        return None
    slope = float(dq @ dth) / float(dth @ dth)  # q per theta
    n = gear_ratio

    def near(x: float, target: float) -> bool:
        return target / RATIO_FACTOR < x < target * RATIO_FACTOR

    if near(slope, n):
        return None
    seen = f"q moves {slope:.3g} times theta where the gear ratio is {n:g}"
    if near(-slope, n):
        return f"{seen}: one encoder counts the other way; flip it (--scales theta=-1)"
    if near(abs(slope), 1.0):
        return f"{seen}: q looks read after the gear; give the motor angle before it (--scales q={n:g})"
    if near(abs(slope), 1.0 / n):
        return f"{seen}: q and theta look swapped; map them the other way (--columns q=...,theta=...)"
    return f"{seen}: check --gear-ratio and the angles' units (--scales)"


def torque_sign_problem(u: np.ndarray, q: np.ndarray, theta: np.ndarray | None, tau: np.ndarray | None,
                        gear_ratio: float, rate: float) -> str | None:
    """A one-line account where the torque left on the rotor, u - tau/N, gives work back over
    the recording (u's sign flipped) or tau falls as the gear's deflection grows (tau's sign
    flipped), with the flip that restores it; None otherwise. ``tau`` None: a direct drive, u
    alone on the rotor (no gravity in its model either)."""
    if tau is None:
        tau = np.zeros_like(u)
    elif theta is not None:
        r = float(np.corrcoef(tau, q / gear_ratio - theta)[0, 1])
        if r < SPRING_SIGN:
            return (f"tau falls as the gear's deflection q/N - theta grows (correlation {r:.2f}; a spring's rises): "
                    "tau's sign looks opposite; flip it (--scales tau=-1)")
    w = np.gradient(q, 1.0 / rate)
    t = tau / gear_ratio
    exchanged = float(np.mean(np.abs(u * w)) + np.mean(np.abs(t * w)))
    rotor = float(np.mean((u - t) * w))
    if not (exchanged > 0 and rotor < -GIVES_BACK * exchanged):
        return None
    left = "the input u" if not np.any(t) else "the torque left on the rotor, u - tau/N,"
    seen = (f"{left} gives back {-rotor / exchanged:.0%} of the work the torques exchange with the rotor (its "
            "friction would take work out)")
    if float(np.mean((-u - t) * w)) > 0:
        return f"{seen}: u's sign looks opposite to q's; flip it (--scales u=-1)"
    return f"{seen}: check the signs and units of u and tau"
