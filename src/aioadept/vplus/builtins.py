"""The functions and instructions that compiled V+ code calls: one namespace per :class:`Runtime`.

Semantics follow the V+ Language Reference Guide where it is explicit; the choices made where it is silent are
listed in docs/vplus.md ("The emulator").
"""

from __future__ import annotations

import math
import random
import re
from collections.abc import Generator
from typing import Any

from aioadept.errors import RobotError
from aioadept.protocol import ErrorCode
from aioadept.vplus import errors as E
from aioadept.vplus.errors import VPlusError, VPlusHalt
from aioadept.vplus.registry import IMPLEMENTATIONS, builtin
from aioadept.vplus import binary, disk, iodev, status  # noqa: F401  (binary: $LNGB ... register themselves)
from aioadept.vplus import locations as L
from aioadept.vplus.parse import norm
from aioadept.vplus.render import _FMT_CACHE, _FMT_RE, _default_number, _fmt_number, _render  # noqa: F401
from aioadept.vplus.values import _FB, _GOTO, MAX_STRING, _Goto, _LocArray, _Missing, f32  # noqa: F401

# The run time's classes, for annotations only: runtime imports this module, so this one does not import it.
Runtime = Any
Task = Any

_NUM_RE = re.compile(r"\s*[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


def _str(v: Any) -> str:
    if type(v) is not str:
        raise VPlusError(E.ILLEGAL_OPERATION, "*Illegal operation* (a number assigned to a string variable)")
    if len(v) > MAX_STRING:
        raise VPlusError(E.STRING_TOO_LONG, f"*String too long* ({len(v)} characters, at most {MAX_STRING})")
    return v


def _real(v: Any) -> Any:
    """Assignment without SET to a plain name: REAL (float32) for numbers. A location needs SET (V+ Language
    User's Guide v17, p. 111: ``loc_var1 = loc_var2`` "is unacceptable for location and precision-point
    variables"); the compiler refuses the forms it can see, this the rest."""
    if type(v) is float or type(v) is int:
        _FB[0] = v
        return _FB[0]
    if isinstance(v, str):
        raise VPlusError(E.ILLEGAL_OPERATION, "*Illegal operation* (a string assigned to a real variable)")
    raise VPlusError(E.ILLEGAL_OPERATION, "*Illegal operation* (a location is assigned with SET)")


def _defref(c: Any, k: Any) -> float:
    """DEFINED of a parameter: its (container, key) holds a value (a by-value argument is a one-element list,
    where ``k in c`` would test the value, not the index)."""
    if type(c) is list:
        return -1.0 if 0 <= k < len(c) else 0.0
    return -1.0 if k in c else 0.0


def _loc_store(c: dict, key: str, arr: Any, idx: Any, v: Any, name: str) -> None:
    """``SET name[idx] = v``: the array is, or becomes, an array of locations; one holding numbers refuses it."""
    a = arr if arr is not None else c.get(key)
    if a is None:
        a = c[key] = _LocArray()
        a.name = name
    elif type(a) is not _LocArray:
        for x in a.values():
            if type(x) is float or type(x) is int:
                raise VPlusError(E.ILLEGAL_OPERATION, f"*Illegal operation* (array {name}[] holds numbers: a "
                                                      "location cannot be stored in it)")
            break
    dict.__setitem__(a, idx, v)


def _dbl(v: Any) -> float:
    if type(v) is float:
        return v
    if isinstance(v, str):
        raise VPlusError(E.ILLEGAL_OPERATION, "*Illegal operation* (a string assigned to a real variable)")
    return float(v)


def _byval(v: Any) -> Any:
    if type(v) is float:
        _FB[0] = v
        return _FB[0]
    return v


def _arr(container: dict, key: str) -> dict:
    a = container.get(key)
    if a is None:
        a = container[key] = {}
    return a


def vint(v: float) -> int:
    """A real used where V+ needs an integer: rounded to the nearest, halves away from zero (V+ Language User's
    Guide v17, p. 102, "Real and Integer Data Types": "V+ promotes the real to an integer by rounding (not
    truncation)"; 1.6 is 2). Halves: UNCONFIRMED (the manual does not say), away from zero chosen."""
    if type(v) is not float and type(v) is not int:
        raise VPlusError(E.ILLEGAL_OPERATION, "*Illegal operation* (a number is needed)")
    return int(math.floor(v + 0.5)) if v >= 0 else -int(math.floor(0.5 - v))


def _ix(v: float) -> int:
    i = vint(v)
    if i < 0:
        raise VPlusError(E.ILLEGAL_ARRAY_INDEX, f"*Illegal array index* {v:g}")
    return i


class _IxTable(dict):
    """Array index of a value: a dict look-up for 0.0 .. 4095.0 (what indices almost always are), _ix otherwise."""

    def __missing__(self, v: Any) -> int:
        return _ix(v)


_IX = _IxTable({float(i): i for i in range(4096)})


def _decode(c: dict, k: Any, breaks: str, mode: float) -> str:
    s = c[k]
    if type(s) is not str or type(breaks) is not str:
        raise VPlusError(E.ILLEGAL_OPERATION, "*Illegal operation* ($DECODE needs strings)")
    # str.find and str.lstrip instead of a loop over the characters (a server frames every line with $DECODE)
    if mode == 0:
        i = len(s)
        for b in breaks:
            j = s.find(b, 0, i)
            if j >= 0:
                i = j
    else:
        i = len(s) - len(s.lstrip(breaks))
    c[k] = s[i:]
    return s[:i]


def _encv(v: Any, spec: tuple) -> str:
    """One value of a compiled $ENCODE with its format (as _render does it)."""
    if type(v) is str:
        return v
    if isinstance(v, (int, float)):
        return _fmt_number(float(v), spec)
    return repr(v)


def _encode(items: tuple) -> str:
    return _str(_render(items)[0])


@builtin("VAL")
def _val(s: str) -> float:
    m = _NUM_RE.match(s)
    return float(m.group(0)) if m else 0.0


@builtin("$MID")
def _mid(s: str, first: float, n: float) -> str:
    i = vint(first)
    if i < 1:
        raise VPlusError(E.ILLEGAL_VALUE, "*Illegal value* ($MID start below 1)")
    return s[i - 1:i - 1 + max(vint(n), 0)]


@builtin("POS")
def _pos(s: str, sub: str, start: float = 1.0) -> float:
    return float(s.find(sub, max(vint(start), 1) - 1) + 1)


@builtin("ASC")
def _asc(s: str, i: float = 1.0) -> float:
    k = vint(i)
    return float(ord(s[k - 1])) if 1 <= k <= len(s) else -1.0


@builtin("$LEFT")
def _left(s: str, n: float) -> str:
    return s[:max(vint(n), 0)]


@builtin("$RIGHT")
def _right(s: str, n: float) -> str:
    k = vint(n)
    return s[-k:] if k > 0 else ""


@builtin("$CHR")
def _chr(n: float) -> str:
    k = vint(n)
    if not 0 <= k <= 255:
        raise VPlusError(E.ILLEGAL_VALUE, "*Illegal value* ($CHR outside 0..255)")
    return chr(k)


@builtin("$TRUNCATE")
def _truncate(s: str) -> str:
    """$TRUNCATE(string): the characters before the first ASCII NUL (all of them if there is none)."""
    if type(s) is not str:
        raise VPlusError(E.ILLEGAL_OPERATION, "*Illegal operation* ($TRUNCATE needs a string)")
    return s.split("\0", 1)[0]


@builtin("BMASK")
def _bmask(*bits: float) -> float:
    """BMASK(bit, ...): a value with each given bit set; bits are numbered 1 (least significant) to 32."""
    v = 0
    for b in bits:
        if b is None:
            continue
        k = round(b)
        if not 1 <= k <= 32:
            raise VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* (BMASK bit {b:g} outside 1..32)")
        v |= 1 << (k - 1)
    return float(v)


def _io_error(exc: RobotError) -> VPlusError:
    """A signal or hand error of the I/O model as the V+ error of the instruction."""
    if exc.code == ErrorCode.ILLEGAL_SIGNAL:
        return VPlusError(E.ILLEGAL_SIGNAL, f"{E.text(E.ILLEGAL_SIGNAL)} ({exc.message})")
    return VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* ({exc.message})")


def _sig(rt: Runtime):
    def sig(*nums: float) -> float:
        # SIG(n, ...): TRUE if every signal is in the state asked for (n < 0: off). Zero is ignored, as before.
        try:
            return -1.0 if rt.io.sig([n for n in nums if int(n) != 0], rt.now) else 0.0
        except RobotError as exc:
            raise _io_error(exc) from None
    return sig


def _bits(rt: Runtime):
    def bits(first: float, count: float = 1.0) -> float:
        try:
            return float(rt.io.bits(first, count, rt.now))
        except RobotError as exc:
            raise _io_error(exc) from None
    return bits


def _deg(f):
    return lambda x: f(math.radians(x))


def namespace(rt: Runtime) -> dict[str, Any]:
    """The globals of a runtime's generated code: the built-in functions (``_fn_NAME`` and the table ``_fn``)
    and the instructions (``_call``, ``_robot``, ``_type`` ...), each group made by its own function below."""
    fn = _functions(rt)
    ns = {"_fn_" + k.replace("$", "s").replace("#", "h").replace(".", "_"): f for k, f in fn.items()}
    ns.update({
        "_G": rt.globals, "_FB": _FB, "_arr": _arr, "_ix": _ix, "_IX": _IX, "_encv": _encv, "_MC": _MISSING_C,
        "_loc_store": _loc_store, "_defref": _defref, "_str": _str, "_pp": _pp_check, "_loc": _loc_check,
        "_dbl": _dbl, "_real": _real, "_f32": f32, "_byval": _byval, "_MISSING": (_MISSING_C, "?"),
        "_decompose": _decompose_into, "_decode": _decode, "_encode": _encode, "_defined": _defined,
        "_defarr": _defarr, "_last": _last, "_fn": fn, "_compose": _compose, "_fmod": math.fmod, "_Goto": _Goto,
        "_GOTO": _GOTO,
        "_disk_open": lambda T, word, lun, items: disk.open_file(T, word, lun, _render(items)[0] if items else ""),
        "_io_attach": iodev.attach(rt), "_io_detach": iodev.detach(rt), "_io_fclose": iodev.fclose(rt),
        "_io_fopen": iodev.fopen(rt), "_io_read": iodev.read(rt), "_io_write": iodev.write(rt),
        "_io_fcmnd": iodev.fcmnd(rt),
    })
    ns.update(_calls(rt))
    for group in (_tasks, _events, _console_and_io, _signals, _motion, _robot):
        ns.update(group(rt))
    return ns


def _arg(A: tuple, i: int, name: str):
    # An argument omitted or left blank is undefined in the callee (V+ Language User's Guide v17, p. 45,
    # "Undefined Arguments"). Each call gets a container of its own: a callee that assigns to it must not
    # make it defined for the next call (one shared container did).
    if i >= len(A):
        return (_Missing(), name)
    a = A[i]
    if type(a) is dict or type(a) is _Missing:
        raise VPlusError(E.ILLEGAL_OPERATION, f"*Illegal operation* (an array passed for {name})")
    if a[0] is _MISSING_C:
        return (_Missing(), name)
    return a


def _argarr(A: tuple, i: int, name: str) -> dict:
    if i >= len(A):
        return _Missing()         # omitted: undefined in the callee (DEFINED(q[]) is FALSE), its own each call
    a = A[i]
    if type(a) is tuple and a[0] is _MISSING_C:
        return _Missing()         # left blank
    if type(a) is not dict and type(a) is not _Missing:
        raise VPlusError(E.ILLEGAL_OPERATION, f"*Illegal operation* ({name}[] needs an array argument)")
    return a


def _progname(v: Any) -> str:
    if not isinstance(v, str):
        raise VPlusError(E.ILLEGAL_OPERATION, "*Illegal operation* (CALLS needs a string)")
    return norm(v.strip())


def _calls(rt: Runtime) -> dict[str, Any]:
    """CALL, CALLS, arguments, EXECUTE, REACTE, the error path and the clock ticks of WAIT."""

    def static(T: Task, prog: str) -> dict:
        return T.statics.setdefault(prog, {})

    def tick() -> float:
        return rt.next_tick()

    def execute(T: Task, task: Any, prog: str, args: tuple) -> None:
        # by value; an argument left blank is undefined in the program, as for CALL
        rt.start_task(int(task) if task is not None else 0, prog,
                      tuple((_MISSING_C, "?") if a is None else ([_byval(a)], 0) for a in args))

    def reacte(T: Task, prog: str) -> None:
        T.reacte = prog

    def err(T: Task, exc: BaseException, prog: str, line: int) -> Generator:
        return rt.on_error(T, exc, prog, line)

    programs = rt.programs          # filled by compile_all after this namespace is built; never replaced

    def call(T: Task, name: str, args: tuple) -> Generator:
        f = programs.get(name)
        if f is None:
            return rt.call(T, name, args)     # the errors: not executable, undefined
        return f(T, args)

    return {"_static": static, "_arg": _arg, "_argarr": _argarr, "_progname": _progname, "_tick": tick,
            "_ctick": rt.cond_tick, "_call": call, "_execute": execute, "_reacte": reacte, "_err": err}


def _tasks(rt: Runtime) -> dict[str, Any]:
    """HALT, STOP, PAUSE, ABORT, KILL and CYCLE.END."""

    def halt(T: Task, prog: str, line: int) -> None:
        raise VPlusHalt(f"(HALTED) {prog}, line {line}", program=prog, line=line, brakes=True)

    def stop(T: Task) -> None:
        T.stop_cycle = True
        raise VPlusHalt("")

    def pause(T: Task, prog: str, line: int) -> Generator:
        rt.console(T.num, f"(PAUSED) {prog}, line {line}")
        T.paused = True
        if rt.on_task_pause is not None:
            where = rt.module.programs.get(prog)
            T.halted_at = (where.file if where is not None else None, prog, line)
            rt.on_task_pause(T)
        while T.paused:
            yield rt.now + 3600.0
        return None

    def abort(T: Task, nums: tuple) -> None:
        for n in nums or (0,):
            if int(n) == T.num:
                raise VPlusHalt("", brakes=True)
            rt.abort(int(n))

    def kill(T: Task, nums: tuple) -> None:
        for n in nums or (0,):
            rt.kill(int(n))

    def cycle_end(T: Task, nums: tuple) -> None:
        n = int(nums[0]) if nums else 0
        other = rt.tasks.get(n)
        if other is not None:
            other.stop_cycle = True

    return {"_halt": halt, "_stop": stop, "_pause": pause, "_abort": abort, "_kill": kill, "_cycle_end": cycle_end}


def _events(rt: Runtime) -> dict[str, Any]:
    """WAIT.EVENT and SET.EVENT."""

    def wait_event(T: Task, args: tuple) -> Generator:
        # WAIT.EVENT mask, timeout: wait for SET.EVENT of this task (mask 1) or until the timeout (seconds).
        mask = args[0] if args and args[0] is not None else 0
        timeout = args[1] if len(args) > 1 and args[1] is not None else None
        end = None if timeout is None or timeout < 0 else rt.now + float(timeout)
        while True:
            if mask and T.events:
                T.events = 0
                return None
            if end is not None and rt.now >= end:
                return None
            if mask:
                # woken by SET.EVENT or I/O on its LUNs at once (signal_event), else at the timeout; without a
                # timeout it waits for the event only
                T.event_wait = True
                yield end if end is not None else rt.now + 3600.0
            else:
                yield end if end is not None else rt.next_tick()

    def set_event(T: Task, args: tuple) -> None:
        n = int(args[0]) if args and args[0] is not None else T.num
        other = rt.tasks.get(n)
        if other is not None:
            rt.signal_event(other)

    return {"_wait_event": wait_event, "_set_event": set_event}


def _console_and_io(rt: Runtime) -> dict[str, Any]:
    """TYPE, PROMPT, ENABLE/DISABLE and TIMER."""

    def type_(T: Task, items: tuple) -> None:
        text, no_eol = _render(items)
        pend = T.statics.setdefault("\0type", {"s": ""})
        text = pend["s"] + text
        if no_eol:
            pend["s"] = text
            return
        pend["s"] = ""
        for ln in text.split("\r\n"):
            rt.console(T.num, ln)

    def prompt(T: Task, is_str: bool) -> Generator:
        while not rt.input:
            T.io_wait = True
            yield rt.next_tick()
        s = rt.input.popleft()
        return s if is_str else _val(s)

    def switch(T: Task, names: list[str], on: bool) -> None:
        for n in names:
            if n not in rt.switches:
                raise VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* (no switch {n})")
            rt.switches[n] = on
            if n == "DRY.RUN" and rt.robot is not None:
                rt.robot.dry_run = on

    def timer_set(n: float, v: float) -> None:
        # V+ Reference Guide, TIMER instruction: timers 1 to 15; timer 0 is the system clock and cannot be set
        k = vint(n)
        if not 1 <= k <= 15:
            raise VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* (TIMER {k}: the timer number must be 1 to 15)")
        rt.timers[k] = rt.now - float(v)

    return {"_type": type_, "_prompt": prompt, "_switch": switch, "_timer_set": timer_set}


def _signals(rt: Runtime) -> dict[str, Any]:
    """SIGNAL, BITS and PARAMETER HAND.TIME: the digital I/O (aioadept.sim.io)."""

    def signal(T: Task, nums: tuple) -> None:
        # SIGNAL n, ...: outputs and soft signals (aioadept.sim.io: numbering, the hand's valves, the change
        # log); an input or a number that is no signal is an error and changes nothing. Zero is ignored.
        try:
            rt.io.signal([k for k in map(vint, nums) if k != 0], rt.now)
        except RobotError as exc:
            raise _io_error(exc) from None

    def bits_set(T: Task, first: float, count: float, value: float) -> None:
        try:
            rt.io.bits_set(first, count, value, rt.now)
        except RobotError as exc:
            raise _io_error(exc) from None

    def parameter(T: Task, name: str, value: float) -> None:
        # PARAMETER HAND.TIME = s (the compiler refuses every other parameter)
        try:
            rt.io.set_hand_time(float(value))
        except RobotError as exc:
            raise _io_error(exc) from None

    return {"_signal": signal, "_bits_set": bits_set, "_parameter": parameter}


def _no_robot() -> VPlusError:
    return VPlusError(E.ROBOT_NOT_ATTACHED, "*Robot not attached* (the emulator has no robot)")


def _robot_of(rt: Runtime, T: Task):
    """The runtime's robot for task ``T``, attached to task 0 when it first moves (V+: task 0 has the robot
    attached when it starts)."""
    r = rt.robot
    if r is None:
        raise _no_robot()
    r.now_s = rt.now
    if not T.robot_attached and T.num == 0 and r.owner is None:
        r.attach(0)
        T.robot_attached = True
    return r


def _live_robot(rt: Runtime):
    r = rt.robot
    if r is None:
        raise _no_robot()
    r.now_s = rt.now
    return r


def _motion(rt: Runtime) -> dict[str, Any]:
    """Motions and the hand (aioadept.vplus.robot.RobotDevice on the sim's Controller): generators the task
    runs until the motion is done."""

    def drive(T: Task, gen: Generator) -> Generator:
        """Run a RobotDevice motion generator, telling it the time at each resumption."""
        r = rt.robot
        r.now_s = rt.now
        for w in gen:
            T.motion_wait = True          # a BRAKE from another task wakes it (rt.wake_motion_waiters)
            yield w
            r.now_s = rt.now

    def robot(T: Task, kind: str, *args: Any) -> Generator:
        r = _robot_of(rt, T)
        n = T.num
        if kind in ("MOVE", "MOVES"):
            return drive(T, r.move(n, args[0], straight=(kind == "MOVES")))
        if kind in ("APPRO", "APPROS"):
            return drive(T, r.appro(n, args[0], float(args[1]), straight=(kind == "APPROS")))
        if kind in ("DEPART", "DEPARTS"):
            return drive(T, r.depart(n, float(args[0]), straight=(kind == "DEPARTS")))
        if kind == "DELAY":
            return drive(T, r.delay(n, float(args[0])))
        if kind in ("MOVET", "MOVEST"):
            return drive(T, r.movet(n, args[0], float(args[1]), straight=(kind == "MOVEST")))
        return drive(T, r.break_())

    def hand(T: Task, kind: str) -> Generator:
        r = _robot_of(rt, T)
        action = kind.rstrip("I").lower()
        return drive(T, r.hand(T.num, action, immediate=kind.endswith("I")))

    def calibrate(T: Task, mode: Any, status: tuple | None) -> Generator:
        # The emulated arm is calibrated from the start: CALIBRATE waits for the arm to be at rest (no motion of
        # its own, ever) and reports success in ``status`` (1, IOSTAT's convention: UNCONFIRMED, docs/vplus.md)
        r = _robot_of(rt, T)
        r._check_owner(T.num)
        yield from drive(T, r.break_())
        if status is not None:
            status[0][status[1]] = 1.0

    return {"_robot": robot, "_hand": hand, "_calibrate": calibrate}


def _robot(rt: Runtime) -> dict[str, Any]:
    """The robot's settings: BRAKE, SPEED, ACCEL, DURATION, the configuration words and TOOL."""

    def brake(T: Task) -> None:
        if rt.robot is not None:
            rt.robot.brake(rt.now)
            rt.wake_motion_waiters()

    def speed(T: Task, v: float, mode: str | None) -> None:
        r = _robot_of(rt, T)
        if mode == "MONITOR":
            r.monitor_speed = float(v)
        else:
            r.speed(T.num, float(v), always=(mode == "ALWAYS"))

    def accel(T: Task, vals: tuple) -> None:
        ctl = getattr(_robot_of(rt, T), "controller", None)
        if ctl is not None and vals:
            ctl.accel_pct = float(vals[0])

    def select(T: Task, device: str, unit: float) -> None:
        # SELECT ROBOT = n: robot 1 is the one arm; another number is an error (text and code UNCONFIRMED)
        n = vint(unit)
        if n != 1:
            raise VPlusError(E.ILLEGAL_VALUE, f"*Illegal value* (SELECT ROBOT = {n}: the emulator has one robot, "
                                              "robot 1)")

    return {
        "_brake": brake, "_speed": speed, "_accel": accel, "_select": select,
        "_duration": lambda T, v, always: _robot_of(rt, T).set_duration(T.num, float(v), always=always),
        "_config": lambda T, word: _robot_of(rt, T).request_config(T.num, word),
        "_tool": lambda T, t: _robot_of(rt, T).set_tool(T.num, _loc_check(t)),
    }


def _decompose_into(a: dict, first: int, v: Any, dbl: bool) -> None:
    vals = L.decompose(v)
    for i, x in enumerate(vals):
        a[first + i] = float(x) if dbl else f32(x)


def _last(get) -> float:
    try:
        a = get()
    except KeyError:
        return -1.0
    return float(max(a)) if a else -1.0


def _defined(get) -> float:
    try:
        get()
    except (KeyError, VPlusError):
        return 0.0
    return -1.0


def _defarr(get) -> float:
    try:
        a = get()
        if type(a) is _Missing and not a:
            return 0.0            # an array argument the caller did not pass
        return -1.0 if a is not None else 0.0
    except KeyError:
        return 0.0


def _loc_check(v: Any) -> Any:
    if not isinstance(v, L.Transform):
        raise VPlusError(E.ILLEGAL_OPERATION, "*Illegal operation* (not a transformation)")
    return v


def _pp_check(v: Any) -> Any:
    if not isinstance(v, L.PrecisionPoint):
        raise VPlusError(E.ILLEGAL_OPERATION, "*Illegal operation* (not a precision point)")
    return v


def _compose(a: Any, b: Any) -> Any:
    return L.compose(_loc_check(a), _loc_check(b))


def _functions(rt: Runtime) -> dict[str, Any]:
    """The V+ functions by name: the registry's run-time-free implementations (@builtin), then those that read
    the run time (TIMER, SIG, TASK, HERE ...) and the location functions."""

    def timer(n: float = 0.0) -> float:
        # TIMER(-3) and the like (what a server reads several times per command): no integer conversion needed,
        # a real <= -0.5 rounds to a negative number (vint)
        if type(n) is float and n <= -0.5:
            return rt.now - rt.t0
        k = vint(n)
        if k < 0:
            return rt.now - rt.t0
        return rt.now - rt.timers.get(k, rt.t0)

    def iostat(T: Task, lun: float, mode: float = 0.0) -> float:
        if int(mode) == 3:
            # completion of the last no-wait WRITE on the LUN (V+ Language User's Guide, "Output Wait Modes")
            dev = T.luns.get(int(lun))
            state = getattr(dev, "nowait_state", None)
            return float(state()) if state is not None else 1.0
        return float(T.iostat.get(int(lun), 0))

    def error_fn(T: Task, src: float = -1.0, sel: float = 0.0) -> float:
        if int(src) < 0:
            return float(T.last_error)
        other = rt.tasks.get(int(src))
        return float(other.last_error if other else 0)

    def task_fn(T: Task, sel: float | None = None, n: float | None = None) -> float:
        if not sel:
            return float(T.num)
        other = rt.tasks.get(int(n if n is not None else T.num))
        if other is None:
            return 0.0
        return {"running": 4.0, "paused": 2.0}.get(other.state, 0.0)

    def speed_fn(T: Task, sel: float = 0.0) -> float:
        ctl = getattr(_live_robot(rt), "controller", None)
        if ctl is None:
            return 100.0
        return float(ctl.monitor_speed_pct if int(sel) == 0 else ctl.always_speed_pct)

    def parameter_fn(name: str) -> float:
        # PARAMETER(name): what PARAMETER name = value set (HAND.TIME); NOT.CALIBRATED is 0, every robot calibrated
        return float(rt.io.hand_time_s) if name == "HAND.TIME" else 0.0

    fn = dict(IMPLEMENTATIONS)
    fn |= _MATH
    fn |= _LOCATION_FUNCTIONS
    fn |= {
        "TIMER": timer, "SIG": _sig(rt), "IOSTAT": iostat, "TASK": task_fn, "ERROR": error_fn,
        "INRANGE": lambda T, loc: float(_live_robot(rt).inrange(loc)), "HERE": lambda T: _live_robot(rt).here(),
        "#HERE": lambda T: _live_robot(rt).here_ppoint(), "SPEED": speed_fn,
        "SWITCH": lambda *a: -1.0 if rt.switches.get("DRY.RUN") else 0.0, "BITS": _bits(rt),
        "GETC": iodev.getc(rt), "PARAMETER": parameter_fn, "SELECT": lambda device: 1.0,
    }
    fn.update(status.functions(rt))      # STATE(), SWITCH(name): the robot's status (aioadept.vplus.status)
    return fn


_MATH: dict[str, Any] = {
    "$ERROR": lambda c: E.text(c), "INT": lambda x: float(int(x)), "ABS": abs, "SQRT": math.sqrt,
    "SQR": lambda x: x * x, "SIN": _deg(math.sin), "COS": _deg(math.cos), "TAN": _deg(math.tan),
    "ATAN2": lambda y, x: math.degrees(math.atan2(y, x)), "ASIN": lambda x: math.degrees(math.asin(x)),
    "ACOS": lambda x: math.degrees(math.acos(x)), "MAX": lambda *v: float(max(v)), "MIN": lambda *v: float(min(v)),
    "SIGN": lambda x: float((x > 0) - (x < 0)), "FRACT": lambda x: x - int(x), "RANDOM": lambda: random.random(),
    "$TOUPPER": str.upper, "$TOLOWER": str.lower, "$TIME": lambda *a: "", "$DEFAULT": lambda *a: "",
}

_LOCATION_FUNCTIONS: dict[str, Any] = {
    "TRANS": lambda *v: L.trans(*[0.0 if x is None else float(x) for x in v]),
    "INVERSE": lambda t: L.inverse(_loc_check(t)),
    "#PPOINT": lambda *j: L.ppoint(*[0.0 if x is None else float(x) for x in j]),
    "DX": lambda t: _loc_check(t).x, "DY": lambda t: _loc_check(t).y, "DZ": lambda t: _loc_check(t).z,
    "DISTANCE": lambda a, b: L.distance(_loc_check(a), _loc_check(b)),
    "SHIFT": lambda t, dx=0.0, dy=0.0, dz=0.0: L.shift(_loc_check(t), dx, dy, dz),
    "RX": L.rx, "RY": L.ry, "RZ": L.rz, "NULL": lambda: L.NULL, "NORM": lambda t: t,
}


_MISSING_C = _Missing()
