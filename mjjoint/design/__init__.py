"""Design the experiment that separates two rival explanations, and decide between them after it.

``rivals`` (the two fitted models), ``limits`` (what the experiment may do), ``families``
(parameterised inputs), ``loop`` (closed-loop references), ``response`` and ``criterion`` (the
expected log-likelihood ratio, each input's noise floor), ``rehearsal`` (the decision rehearsed
on simulated recordings), ``optimise`` (the search), ``export`` (files), ``record`` (simulated
lab recordings), ``decide`` (which rival a new recording supports).
"""
from .criterion import discrimination, input_floor, prediction_floor, predicted_noise
from .decide import Decision, decide
from .limits import Limits
from .optimise import Design, SearchOptions, design
from .rehearsal import Rehearsal, rehearse
from .rivals import Rival

__all__ = ["Decision", "Design", "Limits", "Rehearsal", "Rival", "SearchOptions", "decide", "design",
           "discrimination", "input_floor", "predicted_noise", "prediction_floor", "rehearse"]
