"""System identification: model structures made of named effects, windowed prediction, fitting."""
