"""The control step: law, safety filter and body, written once for every engine."""
