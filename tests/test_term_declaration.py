"""A new physics term is one declaration: written here, it is simulated by the plugin, fitted
and named by the diagnosis with no other change to mjjoint.

The toy term is a viscoelastic cable from the link to the ground: a spring whose force relaxes
with a time constant, tau_c = -z with z' = (k theta - z) / T (a state and its advance kernel,
besides a torque). It runs in a fresh interpreter, since user terms are read once, when
mjjoint is imported (``physics.catalogue``).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

TERM_MODULE = '''
"""A viscoelastic cable on the link, declared once."""
import math
from dataclasses import dataclass

from mjjoint.identify.effect import Effect, Param
from mjjoint.params import check
from mjjoint.physics.jit import kernel
from mjjoint.physics.term import Term


@dataclass(frozen=True)
class Cable:
    k: float = 1.0          # [N m/rad] spring to the ground
    relax: float = 0.02     # [s] relaxation time of its force

    def __post_init__(self):
        check("k", self.k, 0.0)
        check("relax", self.relax, 0.0, lo_open=True)


@kernel
def cable_torque(blk, o, st, s, q, wq, theta, wtheta):
    return 0.0, -st[s]


@kernel
def cable_advance(blk, o, st, s, q, wq, theta, wtheta, h):
    st[s] += (blk[o + P.k] * theta - st[s]) * (1.0 - math.exp(-h / blk[o + P.relax]))


TERM = Term(section="cable", kinds={"maxwell": Cable}, site="link", doc="viscoelastic cable to the ground",
            states=("z_cable",), torque=cable_torque, advance=cable_advance, default_on=False,
            steady=lambda cable, motion: {"z_cable": cable.k * motion["theta"]})
P = TERM.offsets

EFFECTS = (Effect("cable", "viscoelastic cable from the link to the ground",
                  (Param("cable.k", 0.5, 1e-3, 1e3, unit="N m/rad"),),
                  lambda m, v: (m[0], m[1].with_term("cable", Cable(k=v["cable.k"]))),
                  site="link", term="cable", evidence=("sin_theta",), plot="sin_theta",
                  read=lambda m: None if m[1].term("cable") is None else {"cable.k": m[1].term("cable").k}),)
'''

DRIVER = '''
import json, sys
import numpy as np
import mjjoint
from mjjoint.assets import ArmSpec
from mjjoint.coupling.layout import STATE_NAMES
from mjjoint.diagnosis.loop import DiagnoseOptions
from mjjoint.excitation import Multisine
from mjjoint.identify.structure import Structure
from mjjoint.joint import JointParams
from mjjoint.physics.load import LoadFriction
from mjjoint.modelfile import dump_model_file, load_model_file
from cable_term import Cable

out = {}
# Simulate: a constant motor torque on a joint without Coulomb friction settles where the cable
# holds the gear's torque, theta = N u / k; the cable's state is its relaxed force k theta.
k, n, u0 = 2.0, 160.0, 0.002
joint = JointParams(friction=None, load_friction=LoadFriction(fc=0.0, viscous=3.0)).with_term(
    "cable", Cable(k=k, relax=0.05))
arm = ArmSpec(segments=0, gravity=0.0)
trace = mjjoint.simulate(np.full(20000, u0), arm=arm, joint=joint)
out["theta_end"], out["theta_expected"] = float(trace.theta[-1]), n * u0 / k
out["z_end"] = float(trace.state("z_cable")[-1])
out["state_names"] = list(STATE_NAMES)
# The model file carries it both ways.
path = dump_model_file(sys.argv[1] + "/cable.toml", arm, joint)
out["round_trip"] = load_model_file(path).joint == joint
# A recording of a gear with the cable, fitted with it and diagnosed without it.
gear = {"linear_stiffness.k1": 1e4, "transmission_damping.d": 2.0}
truth = Structure.create(("linear_stiffness", "transmission_damping", "cable"), arm, n, {**gear, "cable.k": 30.0})
u = Multisine(amplitude=0.05, f_min=0.2, f_max=20.0, seed=1).sample(1000.0, 6.0)
rec = sys.argv[1] + "/rec.csv"
mjjoint.Simulator(arm=truth.model_params()[0], joint=truth.model_params()[1]).run(u).to_csv(rec)
fitted = mjjoint.fit(rec, gear_ratio=n, base=["linear_stiffness", "transmission_damping", "cable"], max_iter=15)
out["k_fit"] = fitted.structure.values["cable.k"]
d = mjjoint.diagnose(rec, gear_ratio=n, base=["linear_stiffness", "transmission_damping"],
                     options=DiagnoseOptions(max_rounds=1, candidates=("cable", "input_delay"), fit_iter=10,
                                             screen_iter=6))
out["missing"] = list(d.missing)
print(json.dumps(out))
'''


@pytest.fixture(scope="module")
def declared(tmp_path_factory):
    d = tmp_path_factory.mktemp("term")
    (d / "cable_term.py").write_text(TERM_MODULE)
    env = {**os.environ, "MJJOINT_TERMS": "cable_term",
           "PYTHONPATH": os.pathsep.join([str(d), os.environ.get("PYTHONPATH", "")])}
    run = subprocess.run([sys.executable, "-c", textwrap.dedent(DRIVER), str(d)], env=env, capture_output=True,
                         text=True, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    print(run.stdout.strip().splitlines()[-1])
    return json.loads(run.stdout.strip().splitlines()[-1])


def test_the_plugin_simulates_a_declared_term_with_its_state(declared):
    assert declared["theta_end"] == pytest.approx(declared["theta_expected"], rel=1e-3)
    assert declared["z_end"] == pytest.approx(2.0 * declared["theta_expected"], rel=1e-3)
    # its state follows the chapter's, before the integrator's memory
    assert declared["state_names"] == ["z1", "z2", "omega", "q_r", "w_sign", "x", "z_cable"]


def test_a_model_file_carries_a_declared_term(declared):
    assert declared["round_trip"] is True


def test_fit_recovers_and_diagnosis_names_a_declared_term(declared):
    assert declared["k_fit"] == pytest.approx(30.0, rel=0.02)
    assert declared["missing"] == ["cable"]


def test_a_bad_term_module_is_one_line(tmp_path):
    (tmp_path / "no_term.py").write_text("X = 1\n")
    env = {**os.environ, "MJJOINT_TERMS": "no_term", "PYTHONPATH": str(tmp_path)}
    run = subprocess.run([sys.executable, "-m", "mjjoint", "--version"], env=env, capture_output=True, text=True,
                         timeout=300)
    assert run.returncode != 0
    assert "MJJOINT_TERMS: module 'no_term' defines no TERM" in run.stderr.strip().splitlines()[-1]
