"""Helpers for the two-network cell test (tests/integration/test_topology.py) and scripts/netns_cell.py:
``topology`` builds and removes the namespaces, ``cell`` runs the nodes in them, ``probe.py`` and
``state_relay.py`` are small programs started inside the namespaces. See docs/topology.md."""
