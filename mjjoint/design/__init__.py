"""Design the experiment that separates two rival explanations, and decide between them after it.

``rivals`` (the two fitted models), ``limits`` (what the experiment may do), ``families``
(parameterised inputs), ``response`` and ``criterion`` (the expected log-likelihood ratio),
``optimise`` (the search), ``export`` (files), ``record`` (simulated lab recordings),
``decide`` (which rival a new recording supports).
"""
from .criterion import discrimination, prediction_floor, predicted_noise
from .decide import Decision, decide
from .limits import Limits
from .optimise import Design, SearchOptions, design
from .rivals import Rival

__all__ = ["Decision", "Design", "Limits", "Rival", "SearchOptions", "decide", "design", "discrimination",
           "predicted_noise", "prediction_floor"]
