"""A run over a Ray cluster (``zswarm run --cluster``): reaching the cluster offline, one pinned actor
per node that runs its router and agents as ordinary processes, placement by space, and the launcher
that carries the one-machine supervision over. Ray is imported lazily: zswarm runs without it."""
