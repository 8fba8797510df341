"""Fig. 4: impulse response of a mass on a linear, a hysteretic, and a hysteretic + viscous spring."""
from mjjoint.experiments import hysteretic_spring, script

if __name__ == "__main__":
    script.run((hysteretic_spring,), __doc__)
