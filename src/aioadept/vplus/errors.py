"""V+ errors raised by emulated programs, and the one table of their codes and texts.

The V+ manuals list error codes in the range -300..-1300 with texts such as ``*Undefined value*``. Several exact
numbers could not be confirmed (docs/vplus.md lists them); they are kept here only, so that a correction is one line. Robot
errors carry the codes of :class:`aioadept.protocol.ErrorCode` (the sim's table), so that an error ack built from a
V+ error reads the same as the Python sim's.
"""

from __future__ import annotations

from aioadept.errors import AdeptError
from aioadept.protocol import ErrorCode

UNDEFINED_VALUE = -401          # UNCONFIRMED number
ILLEGAL_VALUE = -410
ILLEGAL_OPERATION = -403        # UNCONFIRMED number
STRING_TOO_LONG = -404          # UNCONFIRMED number
UNDEFINED_PROGRAM = -406
NOT_EXECUTABLE = -408           # UNCONFIRMED number
ILLEGAL_ARRAY_INDEX = -409      # UNCONFIRMED number
DIVISION_BY_ZERO = -412         # UNCONFIRMED number
ILLEGAL_SIGNAL = int(ErrorCode.ILLEGAL_SIGNAL)  # UNCONFIRMED number: SIGNAL/SIG/BITS of no signal, SIGNAL of an input
NO_DATA = -526                  # "*No data received*" (V+ Language User's Guide, Serial Line I/O)
NOT_ATTACHED = -516             # UNCONFIRMED number
DEVICE_ERROR = -500             # UNCONFIRMED number
ROBOT_NOT_ATTACHED = -601       # UNCONFIRMED number
END_OF_FILE = -504              # UNCONFIRMED number: READ past the last record of a disk file
FILE_EXISTS = -503              # UNCONFIRMED number: FOPENW of a file that exists
NONEXISTENT_FILE = -568         # UNCONFIRMED number: FOPENR/FDELETE of a file that does not exist
ILLEGAL_FILE_NAME = -514        # UNCONFIRMED number: a file name V+ cannot have, or one outside the disk folder
FILE_IN_USE = -513              # UNCONFIRMED number: a file open for write elsewhere, a LUN with a file open
NOT_OPEN = -515                 # UNCONFIRMED number: READ/WRITE on a disk LUN with no file open (or the wrong way)
NO_STORAGE = -611               # UNCONFIRMED number and text: program memory full (runtime.STORAGE_LIMIT)
INTERNAL = -1200

TEXT: dict[int, str] = {
    UNDEFINED_VALUE: "*Undefined value*",
    ILLEGAL_VALUE: "*Illegal value*",
    ILLEGAL_OPERATION: "*Illegal operation*",
    STRING_TOO_LONG: "*String too long*",
    UNDEFINED_PROGRAM: "*Undefined program or variable name*",   # V+'s text for a CALL of no program
    NOT_EXECUTABLE: "*Program not executable*",
    ILLEGAL_ARRAY_INDEX: "*Illegal array index*",
    DIVISION_BY_ZERO: "*Division by 0*",
    ILLEGAL_SIGNAL: "*Illegal digital signal*",
    NO_DATA: "*No data received*",
    NOT_ATTACHED: "*Device not attached*",
    DEVICE_ERROR: "*Device error*",
    ROBOT_NOT_ATTACHED: "*Robot not attached to this program*",
    END_OF_FILE: "*Unexpected end of file*",
    FILE_EXISTS: "*File already exists*",
    NONEXISTENT_FILE: "*Nonexistent file*",
    ILLEGAL_FILE_NAME: "*Invalid file name*",
    FILE_IN_USE: "*File already open*",
    NOT_OPEN: "*File not opened*",
    NO_STORAGE: "*Not enough storage area*",
    int(ErrorCode.OUT_OF_REACH): "*Location out of range*",
    int(ErrorCode.JOINT_LIMIT): "*Joint limit*",
    int(ErrorCode.JOINT_JUMP): "*Joint jump*",
    int(ErrorCode.ILLEGAL_VALUE): "*Illegal value*",
    -300: "*Skill failed*",
    -101: "*Connection closed*",
    INTERNAL: "*Emulator internal error*",
}


def text(code: int) -> str:
    """``$ERROR(code)``: the message of a V+ error code."""
    return TEXT.get(int(code), f"*Error {int(code)}*")


class VPlusError(AdeptError):
    """An error of a V+ program: code, text, and where (file, program, source line, task).

    ``fatal`` is set once the error has been offered to the task's REACTE program (or there was none): it then
    unwinds the task's call stack and stops the task.
    """

    def __init__(self, code: int, message: str | None = None, *, program: str | None = None,
                 line: int | None = None, task: int | None = None) -> None:
        self.code = int(code)
        self.message = message or text(code)
        self.program = program
        self.line = line
        self.file: str | None = None
        self.task = task
        self.fatal = False
        super().__init__(str(self))

    def __str__(self) -> str:
        where = ""
        if self.program is not None:
            where = (f" ({self.program}" + (f", line {self.line}" if self.line else "")
                     + (f" of {self.file}" if self.file else "") + ")")
        return f"{self.message}{where}"


class VPlusHalt(BaseException):
    """HALT / ABORT / STOP ending a task's program (not an error).

    ``program`` and ``line``: where HALT executed (None for the others). ``brakes``: the task's robot motion is
    braked (HALT, ABORT of the own task; not STOP, which only ends the program's cycles).
    """

    def __init__(self, text: str = "", *, program: str | None = None, line: int | None = None,
                 brakes: bool = False) -> None:
        super().__init__(text)
        self.program = program
        self.line = line
        self.brakes = brakes
