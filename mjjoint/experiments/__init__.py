"""Numerical examples and lab experiments of Ruderman (2012), reproduced with mjjoint."""
