"""A swarm in its world: scenarios, the prey, faults, metrics, the observer and the tally."""
