"""Shared pytest configuration."""

pytest_plugins = ["vplus_coverage"]  # the V+ line coverage of vplus/ at the end of the run (tests/vplus_coverage.py)
