"""The robot cell on the plant network: an OPC UA server per the Robotics companion specification (OPC 40010-1).

``aioadept opcua`` (docs/opcua.md) is a bus node like ``aioadept state``: it follows the robot.state topic and the
``status`` skill and shows them as a ``MotionDeviceSystemType`` of the OPC Foundation's Robotics information model.
:mod:`aioadept.opcua.mapping` turns a state sample and a status into variable values (pure, no OPC UA library);
:mod:`aioadept.opcua.server` builds the address space with asyncua and writes those values. The DI, IA and Robotics
NodeSet2 files in ``nodesets/`` are the OPC Foundation's (MIT licence, header kept), as npm's
``node-opcua-nodesets`` 2.185.0 ships them.
"""
