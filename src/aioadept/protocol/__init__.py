"""The sans-IO core of the robot line protocol: bytes in, values out, and back.

Nothing in this package imports asyncio, socket or time. The asyncio client (:mod:`aioadept.client`) and the
simulated server (:mod:`aioadept.sim.server`) both drive it::

    framer = LineFramer(max_line=128)
    for item in framer.feed(chunk):            # complete lines (bytes) or Oversize events
        msg = parse_command(item)             # CommandMessage, or raises RemoteProtocolError(code, ...)
    wire = encode_ack(Ack(id, Status.DONE, t_start_s, t_done_s, pose))
    for ack in AckReader().feed(chunk):       # the client side: Ack, or BadAck / Oversize for a non-ack line
        ...

Its errors (``ProtocolError`` and below) are in :mod:`aioadept.errors`, the one module outside this package it
imports besides :mod:`aioadept.geometry` (neither imports anything of aioadept).
"""

from aioadept.protocol.codes import DEFAULT_TEXT, ErrorCode, describe
from aioadept.protocol.framing import DELIMITER, MAX_ACK_LINE, MAX_LINE, LineFramer, Oversize
from aioadept.protocol.messages import (
    HELLO_SKILL,
    HERE_SKILL,
    ID_LENGTH,
    MAX_SKILL_NAME,
    NO_ID,
    PROTOCOL_VERSION,
    STOP_SKILL,
    Ack,
    CommandMessage,
    IdAllocator,
    SkillCall,
    Status,
    check_skill_name,
    encode_ack,
    encode_command,
    format_arg,
    parse_ack,
    parse_command,
    recover_id,
    sanitize_text,
)
from aioadept.protocol.reader import AckReader, BadAck

__all__ = [
    "DEFAULT_TEXT", "DELIMITER", "HELLO_SKILL", "HERE_SKILL", "ID_LENGTH", "MAX_ACK_LINE", "MAX_LINE", "MAX_SKILL_NAME", "NO_ID", "PROTOCOL_VERSION", "STOP_SKILL",
    "Ack", "AckReader", "BadAck", "CommandMessage", "ErrorCode", "IdAllocator", "LineFramer", "Oversize", "SkillCall", "Status",
    "check_skill_name", "describe", "encode_ack", "encode_command", "format_arg", "parse_ack", "parse_command",
    "recover_id", "sanitize_text",
]
