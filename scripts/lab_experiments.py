"""Sec. 4 lab experiments on the simulated arm: impulse and load-shock FRFs, down-chirp and its identification, gravity sweep, step."""
from mjjoint.experiments import lab, script

if __name__ == "__main__":
    script.run((lab,), __doc__)
