"""Packaged benchmark suites (TOML data files read with ``importlib.resources``)."""
