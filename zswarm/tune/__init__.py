"""Tuning: searching the parameter sets the design guidelines allow for the one that performs best."""
