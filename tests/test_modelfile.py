"""Model files: round trips, the shipped examples, and one-line errors naming the key."""
from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from mjjoint.assets import ASSETS_DIR, ArmSpec
from mjjoint.joint import JointParams
from mjjoint.modelfile import ModelFile, dump_model_file, load_model_file, model_mapping
from mjjoint.physics.boucwen import BoucWen
from mjjoint.physics.load import LoadFriction
from mjjoint.physics.ripple import TorqueRipple
from mjjoint.physics.stribeck import StaticFriction
from mjjoint.physics.transmission import Transmission
from mjjoint.physics.twosep import TwoSEP

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

# Every section away from its defaults, and each term kind (incl. switched off) at least once.
VARIANTS = [
    (ArmSpec(segments=2, tip_mass=0.5, rod_ei=123.456, input_delay=1e-3, timestep=2.5e-4),
     JointParams(friction=StaticFriction(fc=0.05, fs=0.09, asym=0.01),
                 transmission=Transmission(gear_ratio=100.0, k1=2e4, k3=0.0, backlash=1e-3,
                                           hysteresis=BoucWen(mu=0.3, n=2.0)),
                 load_friction=None, ripple=TorqueRipple(amplitude=0.01, harmonic=4.0, phase=0.3)),
     2000.0),
    (ArmSpec(segments=0),
     JointParams(link_joint="world", friction=TwoSEP(k=3000.0, b=0.0),
                 transmission=Transmission(hysteresis=None), load_friction=LoadFriction(fc=0.1)),
     500.0),
    (ArmSpec(), JointParams(friction=None), 1000.0),
]


@pytest.mark.parametrize("suffix", [".toml", ".yaml", ".yml"])
@pytest.mark.parametrize("arm, joint, rate", VARIANTS)
def test_round_trip(tmp_path, suffix, arm, joint, rate):
    path = dump_model_file(tmp_path / f"model{suffix}", arm, joint, rate)
    back = load_model_file(path)
    assert back.arm == arm
    assert back.joint == joint
    assert back.sample_rate == rate


def test_default_example_states_the_defaults():
    """Every key of every section, each at its default: a key left out (which would load as its
    default all the same) fails the key-set comparison."""
    path = EXAMPLES / "default.toml"
    written = tomllib.loads(path.read_text(encoding="utf-8"))
    expected = model_mapping()
    assert {s: set(keys) for s, keys in written.items()} == {s: set(keys) for s, keys in expected.items()}
    assert load_model_file(path) == ModelFile()


def test_stiff_linear_example_is_linear_and_stiffer():
    m = load_model_file(EXAMPLES / "stiff_linear.yaml")
    tr = m.joint.transmission
    assert tr.hysteresis is None and tr.k2 == 0 and tr.k3 == 0
    assert tr.k1 > Transmission().k1
    assert isinstance(m.joint.friction, StaticFriction)


def test_empty_file_is_the_default_model(tmp_path):
    (tmp_path / "empty.toml").write_text("")
    (tmp_path / "empty.yaml").write_text("")
    assert load_model_file(tmp_path / "empty.toml") == ModelFile()
    assert load_model_file(tmp_path / "empty.yaml") == ModelFile()


def test_a_section_without_kind_takes_its_first_kind(tmp_path):
    (tmp_path / "m.toml").write_text("[ripple]\namplitude = 0.03\n[friction]\nfc = 0.1\nfs = 0.15\n")
    m = load_model_file(tmp_path / "m.toml")
    assert m.joint.ripple == TorqueRipple(amplitude=0.03)
    assert m.joint.friction == TwoSEP(fc=0.1, fs=0.15)


def test_an_mjcf_path_is_taken_as_the_model():
    xml = ASSETS_DIR / "elastic_joint.xml"
    m = load_model_file(xml)
    assert m.mjcf == xml and m.arm is None and m.joint is None


BAD = [
    ("range.toml", "[transmission]\nk1 = -3\n", "transmission.k1=-3 is outside the allowed range"),
    ("range.yaml", "hysteresis:\n  mu: 1.5\n", "hysteresis.mu=1.5"),
    ("ratio.toml", "[transmission]\ngear_ratio = 1e300\n", "transmission.gear_ratio=1e+300 is outside the allowed range"),
    ("arm.toml", "[arm]\nsegments = 4.5\n", "arm.segments=4.5"),
    ("rate.toml", "[simulation]\nsample_rate = 0\n", "simulation.sample_rate=0"),
    ("section.toml", "[transmision]\nk1 = 3\n", "unknown section 'transmision'"),
    ("key.toml", "[friction]\nkind = \"2sep\"\nfoo = 1\n", "unknown key friction.foo"),
    ("kindkey.toml", "[friction]\nkind = \"static\"\nk = 1000\n", "unknown key friction.k"),
    ("string.toml", "[friction]\nfc = \"abc\"\n", "friction.fc='abc' must be a number"),
    ("quoted.toml", "[friction]\nfc = \"0.1\"\n", "friction.fc='0.1' must be a number"),
    ("yamlexp.yaml", "load_friction:\n  v_eps: 1e-3\n", "load_friction.v_eps='1e-3' must be a number"),
    ("bool.toml", "[transmission]\nk3 = true\n", "transmission.k3=True must be a number"),
    ("name.toml", "[joint]\nlink_joint = 3\n", "joint.link_joint=3 must be a string"),
    ("kind.toml", "[friction]\nkind = \"lugre\"\n", "friction.kind='lugre' is not a known kind"),
    ("required.toml", "[transmission]\nkind = \"none\"\n", "transmission.kind='none'"),
    ("nonekeys.toml", "[hysteresis]\nkind = \"none\"\nmu = 0.3\n", "hysteresis.mu is set"),
    ("nested.toml", "[transmission]\nhysteresis = 3\n", "transmission.hysteresis"),
    ("notsection.yaml", "arm: 3\n", "arm must be a section"),
    ("list.yaml", "- 1\n- 2\n", "must hold sections"),
    ("syntax.toml", "[arm\n", "line 1"),
    ("syntax.yaml", "arm: [1, 2\n", "line 2"),
    ("model.json", "{}", "unsupported model file type '.json'"),
    ("bigint.toml", "[arm]\nrod_length = 1" + "0" * 400 + "\n", "arm.rod_length=1000"),
    ("bigrate.yaml", "simulation:\n  sample_rate: 1" + "0" * 400 + "\n", "beyond the largest number"),
]


@pytest.mark.parametrize("name, text, message", BAD, ids=[b[0] for b in BAD])
def test_bad_files_fail_in_one_line_naming_the_key(tmp_path, name, text, message):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ValueError) as info:
        load_model_file(path)
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith(str(path))  # which file
    assert message in text


def test_missing_file_fails_in_one_line(tmp_path):
    with pytest.raises(ValueError, match="no such file"):
        load_model_file(tmp_path / "missing.toml")
