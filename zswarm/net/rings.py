"""How many samples a subscription's ring channel holds between two drains before the oldest go.

A ring channel's slots (about 250 bytes each with zenoh 1.x) are touched as the ring turns and never
handed back, so a channel's memory grows, however often it is drained, until it holds ``capacity`` of
them: 16384 slots are 4 MB. With channels that size, an agent listening to a dozen cells grew by about
1.3 MB a minute in the soak (``tests/test_soak.py``), towards 4 MB for every cell it listened to.
"""

WIDE_CAPACITY = 16384
"""A subscription that hears every pose of the run (the world, a watch), and liveliness tokens (one per
agent that ever joined: that ring barely turns, and no token may be lost)."""

CELL_CAPACITY = 256
"""A free agent's cells, prey and ticks (and the bare floor's, the same): many ticks' worth of what a
crowded cell brings."""
