"""zswarm: decentralized swarms steered by artificial potential functions over Eclipse Zenoh.

Implements Kim, Wang & Shin (2006), "Decentralized Control of Autonomous Swarm Systems Using
Artificial Potential Functions: Analytical Design Guidelines".
"""

__version__ = "0.1.0"
