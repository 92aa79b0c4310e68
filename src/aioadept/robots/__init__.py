"""Kinematics of each arm, pure (numpy, no I/O): :mod:`aioadept.robots.viper_s850` first.

Both the simulated controller (:mod:`aioadept.sim`) and the vision side's virtual camera use it, so it lives below
both of them: neither has to import the other.
"""
