"""The V+ keywords the manuals list, with where each is described: tells a typo from a word not implemented.

A word the emulator does not know is either no V+ keyword at all (``MOVEE``: a syntax error, as the controller's
editor would report it) or a V+ keyword the emulator does not implement (``MOVEC``: the message says so and names
the manual's page for it). The table is the keyword index of the V+ Language Reference Guide v17 (program
instructions, functions, operators, system switches and parameters) and of the V+ Operating System Reference
Guide (monitor commands, which a program cannot use), as far as we could read them; AdeptVision, AdeptForce and
other options' keywords are not in it. A keyword missing here makes a gap look like a typo; the message then
still names file, line and word, so adding it is one line.

Pure data and two look-ups; nothing here parses or runs code.
"""

from __future__ import annotations

LANG = "V+ Language Reference Guide v17"
OS = "V+ Operating System Reference Guide v17"

_INSTRUCTIONS = """
ABORT ABOVE ACCEL ALIGN ALTER ALTOFF ALTON ANY APPRO APPROS ATTACH AUTO BASE BELOW BITS BRAKE BREAK BY CALIBRATE
CALL CALLP CALLS CASE CLEAR.EVENT CLOSE CLOSEI COARSE CPOFF CPON CYCLE.END DECOMPOSE DEF.DIO DEFBELT
DELAY DEPART DEPARTS DETACH DISABLE DO DRIVE DURATION ELSE ENABLE END ESTOP EXECUTE EXIT FCLOSE FCMND FCOPY
FDELETE FEMPTY FINE FLIP FOPEN FOPENA FOPEND FOPENR FOPENW FOR FSEEK FSET GLOBAL GOTO HALT HERE IF
IGNORE KEYMODE KILL LEFTY LOCAL LOCK MC MCS MOVE MOVEC MOVEF MOVES MOVESF MOVET MOVEST MULTIPLE NEXT NOFLIP
NONULL NOOVERLAP NULL OPEN OPENI OVERLAP PANIC PARAMETER PAUSE PROCEED PROMPT REACT REACTE REACTI READ READY RELAX
RELAXI RELEASE RESET RETURN RETURNE RIGHTY RUNSIG SELECT SET SET.EVENT SETBELT SETDEVICE SIGNAL SINGLE
SOLVE.ANGLES SOLVE.TRANS SPEED STOP SWITCH TIMER TOOL TYPE UNTIL VALUE WAIT WAIT.EVENT WHILE WINDOW WRITE
DEVICE
"""

_FUNCTIONS = """
ABS ACCEL ACOS ASC ASIN ATAN2 BASE BELT BITS BMASK BSTATUS CAS CONFIG COS DEFINED DEVICE DISTANCE DURATION
DX DY DZ ERROR FLTB FRACT FRAME GETC HERE #HERE ID IDENTICAL INRANGE INT INTB INVERSE IOSTAT LAST LATCH #LATCH
LATCHED LEN LNGB MAX MIN NORM NULL OUTSIDE PARAMETER PENDANT #PPOINT POS PRIORITY RANDOM RX RY RZ SCALE SELECT
SHIFT SIG SIG.INS SIGN SIN SOLVE.FLAGS SPEED SQR SQRT STATE STATUS SWITCH TAN TAS TASK TIME TIMER TOOL TPS TRANS
TRANSB VAL WINDOW DBLB
$CHR $DBLB $DECODE $DEFAULT $ENCODE $ERROR $FLTB $ID $INTB $LNGB $MID $TIME $TRANSB $TRUNCATE $UNPACK
"""

_OPERATORS = "AND BAND BOR BXOR COM MOD NOT OR XOR"
_CONSTANTS = "FALSE OFF ON PI TRUE DOUBLE REAL LOC PRECISION"   # and the types of AUTO/LOCAL/GLOBAL

_SWITCHES_PARAMETERS = """
AUTO.POWER.OFF CP DRY.RUN FORCE INTERACTIVE MESSAGES POWER ROBOT SCALE.ACCEL SCALE.ACCEL.ROT SET.SPEED
UPPER HAND.TIME BELT.MODE KERMIT.RETRY KERMIT.TIMEOUT NOT.CALIBRATED SCREEN.TIMEOUT TERMINAL
"""

_MONITOR = """
ABORT BASE CALIBRATE CD COMMANDS COPY CYCLE.END DEFAULT DELETE DELETEL DELETEM DELETEP DELETER DELETES DIRECTORY
DISABLE DO EDIT ENABLE ESTOP EXECUTE FCOPY FDELETE FDIRECTORY FLIST FORMAT FRENAME FSET HERE ID IO KILL LIST
LISTL LISTP LISTR LISTS LOAD MDIRECTORY MODULE NET PANIC PARAMETER POINT PRIME PROCEED RENAME RESET RETRY SEE
SIGNAL SPEED SRV.RESET SSTEP STACK STATUS STORE STOREL STOREM STOREP STORER STORES SWITCH TEACH TESTP TOOL
WAIT.START WHERE XSTEP ZERO
"""


def _words(text: str) -> frozenset[str]:
    return frozenset(text.split())


INSTRUCTIONS = _words(_INSTRUCTIONS)
FUNCTIONS = _words(_FUNCTIONS)
OPERATORS = _words(_OPERATORS)
CONSTANTS = _words(_CONSTANTS)
SWITCHES_PARAMETERS = _words(_SWITCHES_PARAMETERS)
MONITOR_COMMANDS = _words(_MONITOR)
ALL = INSTRUCTIONS | FUNCTIONS | OPERATORS | CONSTANTS | SWITCHES_PARAMETERS | MONITOR_COMMANDS


def is_keyword(word: str) -> bool:
    """Whether ``word`` (any case) is a V+ keyword."""
    return word.upper() in ALL


def where(word: str, *, as_function: bool = False) -> str | None:
    """The manual and page that describe ``word`` as a program would use it, or None if it is no V+ keyword.

    ``as_function``: the word is followed by ``(`` in an expression (``SPEED(1)`` is the function, ``SPEED 50`` the
    instruction)."""
    up = word.upper()
    if as_function and up in FUNCTIONS:
        return f"{LANG}, {up} function"
    if not as_function and up in INSTRUCTIONS:
        return f"{LANG}, {up} program instruction"
    if up in FUNCTIONS:
        return f"{LANG}, {up} function"
    if up in INSTRUCTIONS:
        return f"{LANG}, {up} program instruction"
    if up in SWITCHES_PARAMETERS:
        return f"{LANG}, {up} system switch or parameter"
    if up in MONITOR_COMMANDS:
        return f"{OS}, {up} monitor command (not a program instruction)"
    if up in OPERATORS or up in CONSTANTS:
        return f"{LANG}, {up} operator, constant or declaration type"
    return None
