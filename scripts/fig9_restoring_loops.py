"""Fig. 9: hysteretic restoring torque on a load-release cycle for mu = 1, 0.5, 0.1."""
from mjjoint.experiments import restoring_loops, script

if __name__ == "__main__":
    script.run((restoring_loops,), __doc__)
