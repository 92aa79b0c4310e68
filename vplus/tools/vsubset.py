"""A tiny interpreter for the subset of V+ that the reader's pure programs use (framing, parsing, queueing).

It exists so that tests can run rs.onchunk / rs.online / rs.isnum / rs.itoa / rs.clean against
aioadept.protocol and find logic errors in them. It is NOT V+: it encodes our reading of V+ semantics, and the
assumptions that matter are listed here so that a controller test can confirm or refute them:

- ``$DECODE(var, breaks, 0)`` returns the characters of ``var`` up to the first character that is in ``breaks``
  and removes them from ``var``; mode 1 returns (and removes) the run of break characters at the start.
- ``ASC(s, i)`` is the code of character ``i`` (1-based); ``$MID(s, first, n)`` is 1-based; ``LEN``; ``VAL``;
  ``INT`` truncates; ``$CHR``; TRUE is -1, FALSE 0; relational operators give TRUE/FALSE.
- A FOR loop whose end is below its start runs zero times (the programs guard such loops anyway).
- Arguments that are variables are passed by reference, expressions by value; ``a[]`` passes the array.
- Names are case-sensitive here (the sources write keywords upper case and names lower case).

Robot, I/O and timing instructions (BRAKE, BREAK, WAIT, TYPE, SET, MOVE, ...) are recorded or ignored.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

TRUE, FALSE = -1.0, 0.0
_TOKEN = re.compile(r"""\s*(?:
    (?P<num>\d+\.\d*|\.\d+|\d+)
  | (?P<str>"[^"]*")
  | (?P<fmt>/[A-Z]\d+(?:\.\d+)?)
  | (?P<name>[$#]?[A-Za-z][A-Za-z0-9._]*)
  | (?P<op><>|<=|>=|==|[-+*/(),\[\]<>=:])
)""", re.VERBOSE)


class VError(Exception):
    """An error the V+ program would raise (e.g. a string over 128 characters)."""


class _Return(Exception):
    pass


@dataclass
class Ref:
    container: dict
    key: Any


@dataclass
class Program:
    name: str
    params: list[str]
    lines: list[tuple[int, str]]
    jumps: dict[int, int] = field(default_factory=dict)


def _strip_comment(line: str) -> str:
    """The line without its ';' comment (a ';' inside a string constant does not start one)."""
    in_str = False
    for i, ch in enumerate(line):
        if ch == '"':
            in_str = not in_str
        elif ch == ";" and not in_str:
            return line[:i]
    return line


def load(paths: list[Path]) -> dict[str, Program]:
    progs: dict[str, Program] = {}
    for path in paths:
        cur: Program | None = None
        for n, raw in enumerate(path.read_text(encoding="ascii").split("\n"), 1):
            head = raw.strip()
            m = re.match(r"\.PROGRAM ([a-z][a-z0-9._]*)\((.*)\)", head)
            if m:
                params = [p.strip() for p in m.group(2).split(",") if p.strip()]
                cur = Program(m.group(1), params, [])
            elif head == ".END":
                if cur is not None:
                    _link(cur)
                    progs[cur.name] = cur
                cur = None
            elif cur is not None:
                code = _strip_comment(raw).strip()
                if code:
                    cur.lines.append((n, code))
    return progs


def _link(p: Program) -> None:
    """Precompute where each block statement jumps (pc indices)."""
    stack: list[tuple[str, int, list[int]]] = []
    for pc, (_, code) in enumerate(p.lines):
        w = code.split()[0]
        if w in ("IF", "WHILE", "FOR", "CASE") or code == "DO":
            stack.append((w if code != "DO" else "DO", pc, []))
        elif w == "ELSE":
            stack[-1][2].append(pc)
        elif w in ("VALUE", "ANY"):
            stack[-1][2].append(pc)
        elif code == "END" or w == "UNTIL":
            kind, start, mids = stack.pop()
            p.jumps[start] = pc
            for m in mids:
                p.jumps[m] = pc
            p.jumps[pc] = start
            if kind == "IF" and mids:
                p.jumps[("else", start)] = mids[0]  # type: ignore[index]
            if kind == "CASE":
                p.jumps[("case", start)] = mids  # type: ignore[index]


class Machine:
    def __init__(self, progs: dict[str, Program]) -> None:
        self.progs = progs
        self.globals: dict[str, Any] = {}
        self.log: list[str] = []
        self.pose = [480.014, -0.038, 709.975, 0.0, 179.995, 0.004]   # what HERE + DECOMPOSE give
        self.joints = [0.0, -90.0, 180.0, 0.0, 90.0, 0.0]
        self.inrange = 0.0                                          # what INRANGE returns
        self.on_break = None                                        # called at BREAK (the other task runs)
        self.move_error = 0                                         # V+ error code the next MOVE raises
        self.reacte: str | None = None
        self.last_error = 0

    # -- variables ---------------------------------------------------------------------------------------------
    def _scope(self, frame: dict, name: str) -> dict:
        return frame if name in frame else self.globals

    def get(self, frame: dict, name: str, index: Any = None) -> Any:
        scope = self._scope(frame, name)
        if name not in scope:
            raise VError(f"undefined variable {name}")
        val = scope[name]
        if isinstance(val, Ref):
            val = val.container[val.key]
        if index is None:
            return val
        if not isinstance(val, dict) or index not in val:
            raise VError(f"undefined array element {name}[{index}]")
        return val[index]

    def put(self, frame: dict, name: str, value: Any, index: Any = None) -> None:
        if isinstance(value, str) and len(value) > 128:
            raise VError(f"string over 128 characters assigned to {name}")
        scope = self._scope(frame, name)
        if index is None:
            cur = scope.get(name)
            if isinstance(cur, Ref):
                cur.container[cur.key] = value
            else:
                scope[name] = value
        else:
            arr = scope.setdefault(name, {})
            if isinstance(arr, Ref):
                arr = arr.container[arr.key]
            arr[index] = value

    # -- expressions -------------------------------------------------------------------------------------------
    def tokens(self, text: str) -> list[tuple[str, str]]:
        out, pos = [], 0
        text = text.rstrip()
        while pos < len(text):
            m = _TOKEN.match(text, pos)
            if not m or m.end() == pos:
                raise VError(f"cannot tokenize {text[pos:]!r}")
            kind = m.lastgroup
            out.append((kind, m.group(kind)))
            pos = m.end()
        return out

    def eval(self, frame: dict, text: str) -> Any:
        toks = self.tokens(text)
        val, i = self._or(frame, toks, 0)
        if i != len(toks):
            raise VError(f"trailing tokens in {text!r}")
        return val

    def _or(self, f, t, i):
        a, i = self._and(f, t, i)
        while i < len(t) and t[i] == ("name", "OR"):
            b, i = self._and(f, t, i + 1)
            a = TRUE if (a or b) else FALSE
        return a, i

    def _and(self, f, t, i):
        a, i = self._not(f, t, i)
        while i < len(t) and t[i] == ("name", "AND"):
            b, i = self._not(f, t, i + 1)
            a = TRUE if (a and b) else FALSE
        return a, i

    def _not(self, f, t, i):
        if i < len(t) and t[i] == ("name", "NOT"):
            a, i = self._not(f, t, i + 1)
            return (FALSE if a else TRUE), i
        return self._cmp(f, t, i)

    def _cmp(self, f, t, i):
        a, i = self._add(f, t, i)
        ops = {"==": lambda x, y: x == y, "<>": lambda x, y: x != y, "<": lambda x, y: x < y,
               ">": lambda x, y: x > y, "<=": lambda x, y: x <= y, ">=": lambda x, y: x >= y}
        if i < len(t) and t[i][0] == "op" and t[i][1] in ops:
            op = t[i][1]
            b, i = self._add(f, t, i + 1)
            if isinstance(a, str) != isinstance(b, str):
                raise VError("comparison of a string with a number")
            a = TRUE if ops[op](a, b) else FALSE
        return a, i

    def _add(self, f, t, i):
        a, i = self._mul(f, t, i)
        while i < len(t) and t[i] in (("op", "+"), ("op", "-")):
            op = t[i][1]
            b, i = self._mul(f, t, i + 1)
            if op == "+":
                if isinstance(a, str) != isinstance(b, str):
                    raise VError("+ of a string and a number")
                a = a + b
                if isinstance(a, str) and len(a) > 128:
                    raise VError("string expression over 128 characters")
            else:
                a = a - b
        return a, i

    def _mul(self, f, t, i):
        a, i = self._unary(f, t, i)
        while i < len(t) and t[i] in (("op", "*"), ("op", "/")):
            op = t[i][1]
            b, i = self._unary(f, t, i + 1)
            a = a * b if op == "*" else a / b
        return a, i

    def _unary(self, f, t, i):
        if t[i] == ("op", "-"):
            a, i = self._unary(f, t, i + 1)
            return -a, i
        return self._atom(f, t, i)

    def _args(self, f, t, i):
        """Raw argument token lists of a call starting at '('."""
        assert t[i] == ("op", "(")
        depth, start, args, i = 0, i + 1, [], i
        while True:
            kind, v = t[i]
            if v in ("(", "["):
                depth += 1
            elif v in (")", "]"):
                depth -= 1
                if depth == 0:
                    if i > start:
                        args.append(t[start:i])
                    return args, i + 1
            elif v == "," and depth == 1:
                args.append(t[start:i])
                start = i + 1
            i += 1

    def _atom(self, f, t, i):
        kind, v = t[i]
        if kind == "num":
            return float(v), i + 1
        if kind == "str":
            return v[1:-1], i + 1
        if v == "(":
            a, i = self._or(f, t, i + 1)
            assert t[i] == ("op", ")")
            return a, i + 1
        if kind == "name":
            if v in ("TRUE", "FALSE"):
                return (TRUE if v == "TRUE" else FALSE), i + 1
            if i + 1 < len(t) and t[i + 1] == ("op", "(") and (v.isupper() or v.startswith("$") and v[1:].isupper()):
                args, j = self._args(f, t, i + 1)
                return self._func(f, v, args), j
            if i + 1 < len(t) and t[i + 1] == ("op", "["):
                idx, j = self._or(f, t, i + 2)
                assert t[j] == ("op", "]")
                return self.get(f, v, idx), j + 1
            return self.get(f, v), i + 1
        raise VError(f"unexpected {v!r}")

    def _val(self, f, toks):
        v, j = self._or(f, toks, 0)
        assert j == len(toks)
        return v

    def _ref(self, f, toks) -> tuple[str, Any]:
        name = toks[0][1]
        if len(toks) == 1:
            return name, None
        return name, self._val(f, toks[2:-1])

    def _func(self, f, name, args):
        if name == "$ENCODE":
            out, fmt = "", None
            for a in args:
                if len(a) == 1 and a[0][0] == "fmt":
                    fmt = a[0][1]
                    continue
                v = self._val(f, a)
                if isinstance(v, str):
                    out += v
                else:
                    m = re.match(r"/F(\d+)\.(\d+)", fmt or "")
                    if not m:
                        raise VError(f"number without a /F format in $ENCODE: {fmt}")
                    out += "%*.*f" % (int(m.group(1)), int(m.group(2)), v)
            return out
        if name == "$DECODE":
            var, idx = self._ref(f, args[0])
            s = self.get(f, var, idx)
            breaks, mode = self._val(f, args[1]), self._val(f, args[2])
            k = 0
            while k < len(s) and ((s[k] in breaks) == (mode == 1)):
                k += 1
            self.put(f, var, s[k:], idx)
            return s[:k]
        vals = [self._val(f, a) for a in args]
        if name == "LEN":
            return float(len(vals[0]))
        if name == "$MID":
            s, first, n = vals[0], int(vals[1]), int(vals[2])
            return s[first - 1:first - 1 + max(n, 0)]
        if name == "ASC":
            s, k = vals[0], int(vals[1]) if len(vals) > 1 else 1
            return float(ord(s[k - 1])) if 1 <= k <= len(s) else -1.0
        if name == "$CHR":
            return chr(int(vals[0]))
        if name == "VAL":
            m = re.match(r"\s*[+-]?(\d+\.?\d*|\.\d+)", vals[0])
            return float(m.group(0)) if m else 0.0
        if name == "INT":
            return float(int(vals[0]))
        if name == "ERROR":
            return float(self.last_error)
        if name == "INRANGE":
            return self.inrange
        if name == "SIG":
            return self.globals.get("__sig_%d" % int(vals[0]), FALSE)
        if name == "DEFINED":
            return TRUE
        if name == "$ERROR":
            return f"*error {int(vals[0])}*"
        if name == "TIMER":
            return 0.0
        raise VError(f"function {name} not in the subset")

    # -- statements --------------------------------------------------------------------------------------------
    def call(self, name: str, *args: Any) -> dict:
        """Call a program from Python; args are values (str/float) or Ref/dict for by-reference."""
        prog = self.progs[name]
        frame: dict[str, Any] = {}
        for p, a in zip(prog.params, args):
            frame[p.split("[")[0]] = a
        for p in prog.params[len(args):]:
            frame[p.split("[")[0]] = None
        self._run(prog, frame)
        return frame

    def _call_stmt(self, f, text):
        m = re.match(r"CALL ([a-z][a-z0-9._]*)(\(.*\))\s*\Z", text)
        if not m:
            raise VError(f"bad CALL {text!r}")
        prog = self.progs[m.group(1)]
        toks = self.tokens(m.group(2))
        args, _ = self._args(f, toks, 0)
        frame: dict[str, Any] = {}
        for p, a in zip(prog.params, args):
            pname = p.split("[")[0]
            if p.endswith("[]"):
                arr_name = a[0][1]
                scope = self._scope(f, arr_name)
                arr = scope.setdefault(arr_name, {})
                frame[pname] = arr.container[arr.key] if isinstance(arr, Ref) else arr
            elif a[0][0] == "name" and not a[0][1].isupper() and (len(a) == 1 or a[1] == ("op", "[")) and \
                    (len(a) == 1 or a[-1] == ("op", "]")):
                var, idx = self._ref(f, a)
                scope = self._scope(f, var)
                if idx is None:
                    cur = scope.get(var)
                    frame[pname] = cur if isinstance(cur, Ref) else Ref(scope, var)
                else:
                    arr = scope.setdefault(var, {})
                    frame[pname] = Ref(arr, idx)
            else:
                frame[pname] = self._val(f, a)
        self._run(prog, frame)

    def _run(self, prog: Program, frame: dict) -> None:
        pc, lines = 0, prog.lines
        for_state: dict[int, tuple[str, float]] = {}
        try:
            while pc < len(lines):
                n, code = lines[pc]
                w = code.split()[0]
                if w in ("AUTO", "LOCAL"):
                    for decl in code[len(w):].replace("DOUBLE", "").split(","):
                        name = decl.strip().split("[")[0]
                        frame.setdefault(name, {} if "[" in decl else None)
                elif w == "GLOBAL":
                    pass
                elif w == "IF":
                    if self.eval(frame, code[2:-4]):
                        pass
                    else:
                        pc = prog.jumps.get(("else", pc), prog.jumps[pc])  # type: ignore[arg-type]
                elif w == "ELSE":
                    pc = prog.jumps[pc]
                elif w == "WHILE":
                    if not self.eval(frame, code[5:-2]):
                        pc = prog.jumps[pc]
                elif code == "DO":
                    pass
                elif w == "UNTIL":
                    if not self.eval(frame, code[5:]):
                        pc = prog.jumps[pc]
                elif w == "FOR":
                    m = re.match(r"FOR ([a-z][a-z0-9._]*) = (.+) TO (.+)\Z", code)
                    var = m.group(1)
                    if pc not in for_state:
                        start, end = self.eval(frame, m.group(2)), self.eval(frame, m.group(3))
                        self.put(frame, var, start)
                        for_state[pc] = (var, end)
                    else:
                        self.put(frame, var, self.get(frame, var) + 1)
                    if self.get(frame, var) > for_state[pc][1]:
                        del for_state[pc]
                        pc = prog.jumps[pc]
                elif code == "END":
                    start = prog.jumps[pc]
                    sw = lines[start][1].split()[0]
                    if sw in ("WHILE", "FOR"):
                        pc = start
                        continue
                elif w == "CALL":
                    self._call_stmt(frame, code)
                elif w == "RETURN":
                    raise _Return
                elif w == "CALLS":
                    m = re.match(r"CALLS (\$[a-z][a-z0-9._]*)\((.*)\)\Z", code)
                    target = self.get(frame, m.group(1))
                    self.log.append(f"CALLS {target}")
                    self._call_stmt(frame, f"CALL {target}({m.group(2)})")
                elif w in ("SET", "HERE"):
                    self.log.append(code)
                    target = code.split()[1]
                    self.put(frame, target, "location")
                elif w == "DECOMPOSE":
                    m = re.match(r"DECOMPOSE ([a-z][a-z0-9._]*)\[\] = (#?)", code)
                    values = self.joints if m.group(2) else self.pose
                    for j, v in enumerate(values):
                        self.put(frame, m.group(1), float(v), float(j))
                elif w == "SIGNAL":
                    self.log.append(code)
                    v = self.eval(frame, code[6:])
                    self.globals["__sig_%d" % abs(int(v))] = TRUE if v > 0 else FALSE
                elif w == "BREAK":
                    self.log.append(code)
                    if self.on_break is not None:
                        hook, self.on_break = self.on_break, None
                        hook()
                elif w == "REACTE":
                    self.reacte = code.split()[1]
                elif w == "MOVE" and self.move_error:
                    # a robot error: V+ calls the REACTE program; RETURNE resumes after this step
                    self.last_error, self.move_error = self.move_error, 0
                    self.log.append(f"ERROR {self.last_error} at {code}")
                    if self.reacte is None:
                        raise VError(f"error {self.last_error} with no REACTE: the task would halt")
                    handler, self.reacte = self.reacte, None
                    self._call_stmt(frame, f"CALL {handler}()")
                elif w in ("BRAKE", "WAIT", "TYPE", "ATTACH", "DETACH", "MOVE", "SPEED", "TOOL", "EXECUTE",
                           "RETURNE"):
                    self.log.append(code)
                else:
                    m = re.match(r"([$#]?[a-z][a-z0-9._]*)(\[(.+)\])? = (.+)\Z", code)
                    if not m:
                        raise VError(f"{prog.name}:{n}: statement not in the subset: {code!r}")
                    idx = self.eval(frame, m.group(3)) if m.group(2) else None
                    self.put(frame, m.group(1), self.eval(frame, m.group(4)), idx)
                pc += 1
        except _Return:
            pass
