"""Fig. 2: rigid joint (Eq. 2) against elastic joints (Eq. 3, K = 1e3, 1e8): step and amplitude response."""
from mjjoint.experiments import linear_joint, script

if __name__ == "__main__":
    script.run((linear_joint,), __doc__)
