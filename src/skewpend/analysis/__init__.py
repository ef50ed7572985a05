"""Analyses of the motion built on the symbolic and numeric layers: normal modes and sweeps."""
