"""Fig. 8: static Stribeck map and 2SEP frictional lag under cyclic velocity of increasing frequency."""
from mjjoint.experiments import friction_lag, script

if __name__ == "__main__":
    script.run((friction_lag,), __doc__)
