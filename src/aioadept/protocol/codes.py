"""The one table of error codes carried by ``error`` acks.

Codes are negative integers in the V+ error-code range (-300 .. -1300) so that they read like controller errors.
The exact numbers V+ uses for "undefined program" or "location out of range" could not be confirmed; these are
ours, chosen once and kept stable. Both the simulated controller and the V+ modules in ``vplus/`` use this table.
"""

from __future__ import annotations

from enum import IntEnum


class ErrorCode(IntEnum):
    """Error codes of the ``error`` ack (wire value = the integer)."""

    SKILL_FAILED = -300
    """A skill raised an error that has no more specific code."""
    MALFORMED_MESSAGE = -401
    """The line does not follow ``ID:SKILL[:ARGS]`` (bad ID, bad characters, empty fields)."""
    LINE_TOO_LONG = -402
    """The line is longer than 128 characters, the V+ string limit."""
    UNKNOWN_SKILL = -406
    """No skill of that name is registered ("undefined program")."""
    WRONG_ARGUMENT_COUNT = -407
    """The skill takes another number of arguments."""
    ILLEGAL_VALUE = -410
    """An argument is not a finite decimal number, or is out of its range (e.g. speed outside 0..100)."""
    ILLEGAL_SIGNAL = -411
    """A signal number that is no signal of the controller (outputs 1-512, inputs 1001-1512, soft 2001-2512), or
    of the wrong kind (an input given to ``signal``). A sim code; V+'s own number was not confirmed."""
    SIGNAL_TIMEOUT = -1110
    """``wait_sig``: the signal did not reach the state asked for within the timeout. A sim code."""
    OUT_OF_REACH = -610
    """The target location is outside the robot's workspace ("location out of range")."""
    JOINT_LIMIT = -1003
    """The target, or the path to it, passes a joint limit."""
    JOINT_JUMP = -1004
    """Reaching the target would move a joint far more than the size of the Cartesian move justifies (a wrist
    flip, a swing through a singularity); refused before any motion. A sim code, not a confirmed V+ number."""
    SERVER_BUSY = -530
    """The server refuses the connection (too many clients, address not allowed)."""
    INTERNAL = -1200
    """The server failed in a way that is its own fault."""


DEFAULT_TEXT: dict[ErrorCode, str] = {
    ErrorCode.SKILL_FAILED: "skill failed",
    ErrorCode.MALFORMED_MESSAGE: "malformed message",
    ErrorCode.LINE_TOO_LONG: "line too long",
    ErrorCode.UNKNOWN_SKILL: "undefined skill",
    ErrorCode.WRONG_ARGUMENT_COUNT: "wrong number of arguments",
    ErrorCode.ILLEGAL_VALUE: "illegal value",
    ErrorCode.ILLEGAL_SIGNAL: "illegal digital signal",
    ErrorCode.SIGNAL_TIMEOUT: "signal wait timed out",
    ErrorCode.OUT_OF_REACH: "location out of range",
    ErrorCode.JOINT_LIMIT: "joint limit",
    ErrorCode.JOINT_JUMP: "joint jump",
    ErrorCode.SERVER_BUSY: "server busy",
    ErrorCode.INTERNAL: "internal error",
}


def describe(code: int) -> str:
    """The name of a code if it is in the table, else ``"code N"`` (peers may send codes we do not know)."""
    try:
        return ErrorCode(code).name
    except ValueError:
        return f"code {code}"
