"""Rerun recordings: writing (logging and blueprints), reading back, recomputing a run's metrics from
its states, and repairing the file of a writer that was killed."""
