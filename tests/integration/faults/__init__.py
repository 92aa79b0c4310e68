"""Helpers of the fault matrix (``tests/integration/test_fault_matrix.py``): real processes, a byte-chopping TCP
relay, toxiproxy driven over its HTTP API, and a network namespace for half-open connections.

Nothing here mocks a part of aioadept: every helper starts or connects the real thing (``aioadept sim``,
``aioadept vision``, a RobotClient in its own process, toxiproxy-server) on 127.0.0.1 or on a veth link.
"""
