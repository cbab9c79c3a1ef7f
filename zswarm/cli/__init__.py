"""Every command: ``zswarm design|sim|run|sweep|replay|compare|certs|bench ...`` (see
:mod:`zswarm.cli.main`). The only layer that may import every other."""
