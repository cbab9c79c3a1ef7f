"""Agent processes: ``python -m agents --id I --run RUN [zenoh args] [--set NAME=VALUE ...]``."""
