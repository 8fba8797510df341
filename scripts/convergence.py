"""The shipped step against a 100x finer one, per physics term and for the full joint: prints
the table of docs/design.md and writes it to OUT/convergence.md (about a minute)."""
from mjjoint.experiments import convergence, script

if __name__ == "__main__":
    script.run((convergence,), __doc__)
