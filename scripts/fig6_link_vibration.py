"""Fig. 6: link vibrations of the joint load (Eq. 10) for two link stiffnesses under a lagged torque step."""
from mjjoint.experiments import link_vibration, script

if __name__ == "__main__":
    script.run((link_vibration,), __doc__)
