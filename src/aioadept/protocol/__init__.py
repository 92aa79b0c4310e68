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

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the names as a type checker and the API reference see them; imported lazily below
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

_WHERE = {
    **dict.fromkeys(("DEFAULT_TEXT", "ErrorCode", "describe"), "codes"),
    **dict.fromkeys(("DELIMITER", "MAX_ACK_LINE", "MAX_LINE", "LineFramer", "Oversize"), "framing"),
    **dict.fromkeys(("HELLO_SKILL", "HERE_SKILL", "ID_LENGTH", "MAX_SKILL_NAME", "NO_ID", "PROTOCOL_VERSION",
                     "STOP_SKILL", "Ack", "CommandMessage", "IdAllocator", "SkillCall", "Status", "check_skill_name",
                     "encode_ack", "encode_command", "format_arg", "parse_ack", "parse_command", "recover_id",
                     "sanitize_text"), "messages"),
    **dict.fromkeys(("AckReader", "BadAck"), "reader"),
}


def __getattr__(name: str):
    # Each name is imported from its module on first use: a tool that needs only the error codes (the V+ source
    # checker, through aioadept.vplus.errors) does not pay for the messages' imports (the pose brings numpy)
    if name in _WHERE:
        return getattr(importlib.import_module(f"aioadept.protocol.{_WHERE[name]}"), name)
    raise AttributeError(f"module 'aioadept.protocol' has no attribute {name!r}")


__all__ = [
    "DEFAULT_TEXT", "DELIMITER", "HELLO_SKILL", "HERE_SKILL", "ID_LENGTH", "MAX_ACK_LINE", "MAX_LINE", "MAX_SKILL_NAME", "NO_ID", "PROTOCOL_VERSION", "STOP_SKILL",
    "Ack", "AckReader", "BadAck", "CommandMessage", "ErrorCode", "IdAllocator", "LineFramer", "Oversize", "SkillCall", "Status",
    "check_skill_name", "describe", "encode_ack", "encode_command", "format_arg", "parse_ack", "parse_command",
    "recover_id", "sanitize_text",
]
