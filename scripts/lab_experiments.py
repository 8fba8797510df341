"""Sec. 4 lab experiments on the simulated arm: impulse FRFs, down-chirp, gravity sweep, step."""
from mjjoint.experiments import lab, script

if __name__ == "__main__":
    script.run((lab,), __doc__)
