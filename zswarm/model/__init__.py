"""The paper's model: parameters, potentials and forces, design guidelines, scenarios, the prey,
neighbour search, fault models and metrics. Pure numpy; knows nothing of processes, files or the
network."""
