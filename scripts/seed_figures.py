"""All of the seed paper's numerical examples (Figs. 2, 4, 6, 8, 9) and lab experiments (Sec. 4)."""
from __future__ import annotations

from mjjoint.experiments import (
    friction_lag,
    hysteretic_spring,
    lab,
    linear_joint,
    link_vibration,
    restoring_loops,
    script,
)

EXPERIMENTS = (linear_joint, hysteretic_spring, link_vibration, friction_lag, restoring_loops, lab)


if __name__ == "__main__":
    script.run(EXPERIMENTS, __doc__)
