"""Helpers shared by the Python tests (network namespaces, simulator processes)."""
