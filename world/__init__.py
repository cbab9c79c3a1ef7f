"""The world process: ``python -m world --run RUN --scenario NAME --record FILE.rrd``."""
