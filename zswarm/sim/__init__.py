"""The centralized reference simulator: the model's equations stepped for the whole swarm at once,
with the same faults as the network applied through a seeded channel. Never imports the network."""
