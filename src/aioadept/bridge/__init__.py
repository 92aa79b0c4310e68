"""The robot bridge: one controller connection shared by several applications over Zenoh.

- :mod:`aioadept.bridge.wire`: the query and reply payloads (sans-IO).
- :mod:`aioadept.bridge.node`: :class:`Bridge`, the node ``aioadept bridge`` runs (the one writer).
- :mod:`aioadept.bridge.claim`: one bridge per robot name (:class:`BridgeNameTaken`).
- :mod:`aioadept.bridge.client`: :class:`BridgeClient`, RobotClient's API for an application.

See docs/bridge.md. Needs the ``[zenoh]`` extra at run time; importing this package does not import Zenoh.
"""

from aioadept.bridge.client import BridgeClient
from aioadept.errors import BridgeNameTaken, BridgeRefused
from aioadept.bridge.node import Bridge, BridgeStats

__all__ = ["Bridge", "BridgeClient", "BridgeNameTaken", "BridgeRefused", "BridgeStats"]
