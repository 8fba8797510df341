"""The stability check's apparent inertias are memoised on what the mass matrix depends on: a
model that differs in its masses gets its own, one that differs only in the joint physics
shares them, and either way they equal a fresh computation."""
from __future__ import annotations

import numpy as np

from mjjoint.assets import ArmSpec, load_model
from mjjoint.assets.stability import _apparent_inertias, apparent_inertias
from mjjoint.joint import JointParams
from mjjoint.physics.transmission import Transmission


def _inertias(arm: ArmSpec, joint: JointParams = JointParams()) -> tuple[np.ndarray, np.ndarray]:
    model = load_model(arm=arm, joint=joint)
    return apparent_inertias(model, ["link"]), _apparent_inertias(model, ["link"], 16, 0)


def test_the_memo_follows_the_masses():
    light, light_fresh = _inertias(ArmSpec(tip_mass=1.0))
    heavy, heavy_fresh = _inertias(ArmSpec(tip_mass=3.0))
    np.testing.assert_array_equal(light, light_fresh)
    np.testing.assert_array_equal(heavy, heavy_fresh)
    assert not np.allclose(light, heavy)
    stiff = JointParams(transmission=Transmission(gear_ratio=160.0, k1=5e3))
    again, _ = _inertias(ArmSpec(tip_mass=1.0), stiff)
    np.testing.assert_array_equal(again, light)
