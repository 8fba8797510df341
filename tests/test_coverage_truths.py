"""The interval coverage's own truths (``benchmark.cases.COVERAGE_ONLY``: effects the concealed set
does not hold, each beside the concealed cases' base): fitted from the catalogue's start as
``mjjoint fit`` fits, on seed 0's recording, the fit explains the recording to its floor and the
effect's parameters are identifiable, each 95 % interval holding its truth. The rate over many
seeds is scripts/interval_coverage.py's (docs/diagnosis.md, "Intervals: coverage measured")."""
from __future__ import annotations

import pytest

from mjjoint.benchmark.cases import COVERAGE_ONLY
from mjjoint.benchmark.coverage import coverage_fit, covered
from mjjoint.identify.effects import EFFECTS


@pytest.mark.slow
@pytest.mark.parametrize("effect", COVERAGE_ONLY)
def test_a_coverage_truth_is_recovered_within_its_interval(effect):
    case, result, explained, _ = coverage_fit(effect, seed=0, duration=8.0)
    assert explained, result.nrmse_test
    held = covered(result, case.truth, explained)
    for p in EFFECTS[effect].params:
        assert held[p.name] == (True, True), (p.name, case.truth.values[p.name], result.intervals[p.name],
                                              result.warnings)


def test_an_unknown_check_is_refused_by_name():
    with pytest.raises(ValueError, match="'some' is not one of own, all, none"):
        coverage_fit("backlash", seed=0, duration=1.0, check="some")
