"""The design checks: Propositions 1-5, the swarm and body checks, the nearest passing set."""
