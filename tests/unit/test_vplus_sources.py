"""Checks of the V+ RobotServer in vplus/ that need no controller (docs/vplus.md says what stays untested).

1. Static: the .V2 structure the loader expects, V+ name and string limits, the skill table against the
   simulator's, the error codes against the one table, the block structure of every program.
2. Behaviour: the programs run in the V+ emulator (aioadept.vplus, virtual time, the simulated Viper) against
   aioadept.protocol (framing, parsing, acks, refusals, stop during a break, REACTE). That checks our logic on
   our reading of V+ (docs/vplus.md, "The emulator"), not V+ itself.
"""

from __future__ import annotations

import inspect
import random
import re
from dataclasses import dataclass, field
from pathlib import Path

import pytest

import aioadept.commands as commands
from aioadept.errors import RemoteProtocolError
from aioadept.vplus import Emulator
from aioadept.vplus.loader import strip_comment as vplus_strip_comment
from aioadept.protocol import (
    HELLO_SKILL,
    HERE_SKILL,
    NO_ID,
    PROTOCOL_VERSION,
    STOP_SKILL,
    ErrorCode,
    LineFramer,
    Oversize,
    Status,
    parse_ack,
    parse_command,
    recover_id,
)

VPLUS = Path(__file__).resolve().parents[2] / "vplus"
FILES = sorted(VPLUS.glob("*.V2"))

MAX_NAME = 15          # V+ program and variable names (longer variable names are silently truncated)
MAX_STRING = 128       # V+ string values and constants
MAX_LINE = 120         # the original AdeptServer's longest line is about 110 characters

# The skills of the paper and our extensions, as the client (commands.py) and protocol core know them.
PAPER_SKILLS = {"move_to", "move_joints", "move_rel_world", "move_rel_tool", "move_rel_joints", "break",
                "set_speed", "enable_air", "disable_air"}
EXTENSION_SKILLS = {STOP_SKILL, HERE_SKILL, HELLO_SKILL}
# Argument counts, for when the simulator's table cannot be imported.
FALLBACK_NARGS = {"move_to": 6, "move_joints": 6, "move_rel_world": 6, "move_rel_tool": 6, "move_rel_joints": 6,
                  "break": 0, "set_speed": 1, "enable_air": 0, "disable_air": 0, "here": 0, "hello": 0}

SECTION_KINDS = {".LOCATIONS", ".PRECISIONPOINTS", ".REALS", ".DOUBLES", ".STRINGS"}
PROGRAM_RE = re.compile(r"\.PROGRAM ([A-Za-z][A-Za-z0-9._]*)\((.*)\)(?:\s*;.*)?\Z")
NAME_RE = re.compile(r"[a-z][a-z0-9._]*\Z")
# Keywords we use that are also V+ names; a variable may not be called like one (V+ names are case-blind).
RESERVED = {"abs", "and", "any", "asc", "attach", "brake", "break", "call", "calls", "case", "decompose", "defined",
            "detach", "do", "else", "end", "error", "execute", "false", "fclose", "fopen", "for", "global", "here",
            "if", "inrange", "int", "iostat", "len", "mod", "move", "not", "of", "or", "pos", "read", "reacte",
            "return", "returne", "set", "sig", "signal", "speed", "status", "step", "stop", "task", "then",
            "timer", "to", "tool", "trans", "true", "type", "until", "val", "value", "wait", "while", "write"}


@dataclass
class Program:
    name: str
    params: str
    file: str
    line: int
    body: list[tuple[int, str]] = field(default_factory=list)   # (line number, raw line)


def strip_comment(line: str) -> str:
    """The line without its ';' comment (a ';' inside a string constant does not start one): the emulator's."""
    return vplus_strip_comment(line)


def code_and_strings(line: str) -> tuple[str, list[str]]:
    """Code with string constants blanked out, and the string constants."""
    code = strip_comment(line)
    strings = re.findall(r'"([^"]*)"', code)
    return re.sub(r'"[^"]*"', '""', code), strings


def parse(path: Path) -> tuple[list[Program], list[str]]:
    """Programs of one .V2 file, and structural problems (empty if well formed)."""
    problems: list[str] = []
    programs: list[Program] = []
    current: Program | None = None
    section: str | None = None
    for n, raw in enumerate(path.read_text(encoding="ascii").split("\n"), 1):
        line = raw.rstrip("\r")
        head = line.strip()
        if current is None and section is None:
            if not head:
                continue
            m = PROGRAM_RE.match(head)
            if m:
                current = Program(m.group(1), m.group(2), path.name, n)
            elif head in SECTION_KINDS:
                section = head
            else:
                problems.append(f"{path.name}:{n}: outside .PROGRAM/.END: {head[:40]!r}")
            continue
        if head.startswith(".END") and head == ".END":
            if current is not None:
                programs.append(current)
            current, section = None, None
            continue
        if head.startswith("."):
            problems.append(f"{path.name}:{n}: {head.split()[0]} before .END of the open section")
            continue
        if current is not None:
            current.body.append((n, line))
    if current is not None or section is not None:
        problems.append(f"{path.name}: last section is not closed by .END")
    return programs, problems


def all_programs() -> dict[str, Program]:
    out: dict[str, Program] = {}
    for f in FILES:
        progs, _ = parse(f)
        for p in progs:
            assert p.name not in out, f"{p.name} defined twice ({out[p.name].file}, {p.file})"
            out[p.name] = p
    return out


def python_skills() -> set[str]:
    """Every skill name the client's command classes and the protocol core know."""
    names = set(EXTENSION_SKILLS)
    for _, cls in inspect.getmembers(commands, inspect.isclass):
        skill = getattr(cls, "skill", "")
        if issubclass(cls, commands.Command) and isinstance(skill, str) and skill:
            names.add(skill)
    # skills built directly as SkillCall("name", ...) (set_speed, break)
    names |= set(re.findall(r'SkillCall\("([a-z][a-z0-9._]*)"', inspect.getsource(commands)))
    return names


def expected_nargs() -> dict[str, set[int]]:
    """Argument counts per skill, from the simulator's skill table if it is there."""
    try:
        from aioadept.sim.skills import default_skills
    except Exception:  # the simulator is built elsewhere; fall back to the paper's counts
        return {k: {v} for k, v in FALLBACK_NARGS.items()}
    out: dict[str, set[int]] = {}
    for spec in default_skills():
        counts = getattr(spec, "nargs", None) or getattr(spec, "arg_counts", None)
        if counts is None and hasattr(spec, "nargs"):
            counts = (-1,)  # any count (signal, sig): rs.addskill's -1
        if counts is None:
            counts = next((v for v in vars(spec).values() if isinstance(v, tuple)
                           and all(isinstance(x, int) for x in v)), None)
        if counts is not None and spec.name != STOP_SKILL:
            out[spec.name] = set(counts)
    return out or {k: {v} for k, v in FALLBACK_NARGS.items()}


# ------------------------------------------------------------------------------------------------------------

def test_there_are_v2_modules():
    assert FILES, "no .V2 files in vplus/"
    assert {"rserver.V2", "rsskills.V2", "rsconfig.V2"} <= {f.name for f in FILES}


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_v2_structure_is_well_formed(path: Path):
    data = path.read_bytes()
    bad = sorted({b for b in data if not (32 <= b <= 126 or b in (9, 10, 13))})
    assert not bad, f"{path.name}: non-printable or non-ASCII bytes {bad}"
    programs, problems = parse(path)
    assert not problems, "\n".join(problems)
    assert programs, f"{path.name}: no programs"
    # AdeptServer convention: the first program names the module and does nothing
    first = programs[0]
    assert first.name == path.stem.lower() and first.params == "", f"{path.name}: first program must be {path.stem.lower()}()"
    for n, raw in enumerate(path.read_text(encoding="ascii").split("\n"), 1):
        assert len(raw.expandtabs(8)) <= MAX_LINE, f"{path.name}:{n}: line longer than {MAX_LINE}"


def test_program_names_are_v_plus_names():
    for name, prog in all_programs().items():
        assert NAME_RE.match(name), f"{prog.file}:{prog.line}: {name!r} is not a lowercase V+ name"
        assert len(name) <= MAX_NAME, f"{prog.file}:{prog.line}: program name {name!r} over {MAX_NAME} characters"


def test_every_python_skill_is_a_v_plus_program():
    skills = python_skills()
    assert PAPER_SKILLS | EXTENSION_SKILLS <= skills, "commands.py lost a skill"
    missing = skills - set(all_programs())
    assert not missing, f"skills without a .PROGRAM in vplus/: {sorted(missing)}"


def test_skill_table_matches_the_python_side():
    """rs.init registers each skill (except stop, which the reader serves) with the simulator's argument count."""
    init = all_programs()["rs.init"]
    registered: dict[str, int] = {}
    for _, raw in init.body:
        m = re.search(r'CALL rs\.addskill\("([^"]+)", (-?\d+)\)', strip_comment(raw))
        if m:
            registered[m.group(1)] = int(m.group(2))
    expected = expected_nargs()
    assert set(registered) == set(expected), (sorted(registered), sorted(expected))
    for name, n in registered.items():
        assert n in expected[name], f"{name}: registered with {n} arguments, the simulator takes {expected[name]}"
    assert STOP_SKILL not in registered
    online = "\n".join(raw for _, raw in all_programs()["rs.online"].body)
    assert f'$sk == "{STOP_SKILL}"' in online, "the reader must serve stop itself"


def test_error_code_table_is_the_python_table():
    codes = all_programs()["rs.codes"]
    seen: dict[str, int] = {}
    members: set[str] = set()
    for n, raw in codes.body:
        m = re.match(r"\s*(rs\.e\.[a-z]+) = (-\d+)\s*;\s*ErrorCode\.([A-Z_]+)\s*\Z", raw)
        if not raw.strip() or raw.strip().startswith(";"):
            continue
        assert m, f"rsserver rs.codes line {n}: expected 'rs.e.name = -N ; ErrorCode.NAME', got {raw.strip()!r}"
        var, value, member = m.group(1), int(m.group(2)), m.group(3)
        assert member in ErrorCode.__members__, f"{member} is not in ErrorCode"
        assert ErrorCode[member] == value, f"{var} = {value}, but ErrorCode.{member} = {int(ErrorCode[member])}"
        seen[var] = value
        members.add(member)
    assert members == set(ErrorCode.__members__), f"table incomplete: {set(ErrorCode.__members__) - members}"
    assert len(set(seen.values())) == len(seen)


def test_error_acks_use_only_codes_of_the_table():
    progs = all_programs()
    defined = {m.group(1) for _, raw in progs["rs.codes"].body
               if (m := re.match(r"\s*(rs\.e\.[a-z]+) =", raw))}
    for prog in progs.values():
        for n, raw in prog.body:
            code, _ = code_and_strings(raw)
            for var in re.findall(r"\brs\.e\.[a-z]+\b", code):
                assert var in defined, f"{prog.file}:{n}: {var} is not in rs.codes"
            if prog.name == "rs.codes":
                continue
            assert not re.search(r"rs\.xcode\s*=\s*(-|[1-9])", code), f"{prog.file}:{n}: literal error code"
            m = re.search(r"CALL rs\.enqerr\(([^)]*)\)", code)
            if m:
                code_arg = [a.strip() for a in m.group(1).split(",")][2]
                assert code_arg.startswith("rs.e."), f"{prog.file}:{n}: enqerr code must be one of rs.e.*"


def test_error_messages_fit_an_ack_field():
    """Messages are one trailing field: no ':' (the Python side would read a second field), at most 80."""
    count = 0
    for prog in all_programs().values():
        for n, raw in prog.body:
            code = strip_comment(raw)
            for s in re.findall(r'CALL rs\.enqerr\([^,]+,[^,]+,[^,]+, "([^"]*)"\)', code) + \
                    re.findall(r'\$rs\.xmsg = "([^"]+)"', code):
                count += 1
                assert ":" not in s and 0 < len(s) <= 80, f"{prog.file}:{n}: {s!r} cannot be an ack field"
    assert count >= 10


def test_hello_reports_the_protocol_version():
    body = "\n".join(raw for _, raw in all_programs()[HELLO_SKILL].body)
    m = re.search(r'\$rs\.xtra = "([^"]*)"', body)
    assert m, "hello must set $rs.xtra"
    fields = m.group(1).split(":")
    assert len(fields) == 2 and fields[0] == str(PROTOCOL_VERSION) and fields[1], fields


def test_names_and_strings_respect_v_plus_limits():
    progs = all_programs()
    for prog in progs.values():
        params = [p.strip().lstrip("$#").split("[")[0] for p in prog.params.split(",") if p.strip()]
        for p in params:
            assert NAME_RE.match(p) and len(p) <= MAX_NAME, f"{prog.name}: parameter {p!r}"
        for n, raw in prog.body:
            code, strings = code_and_strings(raw)
            for s in strings:
                assert len(s) <= MAX_STRING, f"{prog.file}:{n}: string constant over {MAX_STRING} characters"
            # lowercase words are user names (keywords are written in uppercase)
            for tok in re.findall(r"[$#]?\b[a-z][a-z0-9._]*", code):
                name = tok.lstrip("$#").rstrip(".")
                assert len(name) <= MAX_NAME, f"{prog.file}:{n}: name {name!r} over {MAX_NAME} characters"
                if name not in progs:
                    assert name not in RESERVED, f"{prog.file}:{n}: variable {name!r} is a V+ keyword"
            for tok in re.findall(r"\b[A-Z][A-Za-z]*[a-z][A-Za-z]*\b", code):
                pytest.fail(f"{prog.file}:{n}: mixed-case word {tok!r} (keywords upper, names lower)")


def test_called_programs_exist():
    progs = all_programs()
    for prog in progs.values():
        for n, raw in prog.body:
            code, _ = code_and_strings(raw)
            for target in re.findall(r"\bCALL\s+([a-z][a-z0-9._]*)\s*\(", code):
                assert target in progs, f"{prog.file}:{n}: CALL of undefined program {target}"
            for target in re.findall(r"\b(?:REACTE|EXECUTE\s+\d+)\s+([a-z][a-z0-9._]*)", code):
                assert target in progs, f"{prog.file}:{n}: {target} is not defined"


# A block's opening word: what its line must match, and the problem when it does not.
_OPENERS = {"IF": (r".*THEN$", "IF without THEN at the end of the line"), "WHILE": (r".*DO$", "WHILE without DO"),
            "FOR": (r"FOR [a-z][a-z0-9._]* = .+ TO .+", "malformed FOR"), "CASE": (r".*OF$", "CASE without OF")}
# A word that continues an open block: the block it must be inside.
_INSIDE = {"ELSE": "IF", "VALUE": "CASE", "ANY": "CASE"}


def block_problems(prog: Program) -> list[str]:
    """Check that control structures open and close in order (a multi-line IF needs END, DO needs UNTIL)."""
    stack: list[tuple[str, int]] = []
    problems = []
    declarations_over = False
    for n, raw in prog.body:
        code = code_and_strings(raw)[0].strip()
        if not code:
            continue
        word = code.split()[0]
        if word in ("AUTO", "LOCAL", "GLOBAL"):
            if declarations_over:
                problems.append(f"{n}: {word} after an executable instruction")
            continue
        declarations_over = True
        if word in _OPENERS:
            pattern, problem = _OPENERS[word]
            if not re.match(pattern, code):
                problems.append(f"{n}: {problem}")
            stack.append((word, n))
        elif code == "DO":
            stack.append(("DO", n))
        elif word in _INSIDE:
            if not stack or stack[-1][0] != _INSIDE[word]:
                problems.append(f"{n}: {word} outside {_INSIDE[word]}")
        elif word == "UNTIL":
            if not stack or stack.pop()[0] != "DO":
                problems.append(f"{n}: UNTIL without DO")
        elif code == "END":
            if not stack:
                problems.append(f"{n}: END without an open block")
            elif stack.pop()[0] == "DO":
                problems.append(f"{n}: DO closed by END instead of UNTIL")
    problems += [f"{n}: {kind} not closed" for kind, n in stack]
    return problems


def test_control_blocks_are_balanced():
    problems = []
    for prog in all_programs().values():
        problems += [f"{prog.file} {prog.name} line {p}" for p in block_problems(prog)]
    assert not problems, "\n".join(problems)


def test_block_checker_catches_mistakes():
    """The checks above are only worth something if they fail on broken programs."""
    def prog(*lines: str) -> Program:
        return Program("p", "", "x.V2", 1, [(i, "\t" + s) for i, s in enumerate(lines, 2)])

    assert block_problems(prog("IF a THEN", "b = 1")) == ["2: IF not closed"]
    assert block_problems(prog("DO", "a = 1", "END"))
    assert block_problems(prog("a = 1", "AUTO b"))
    assert not block_problems(prog("AUTO i", "FOR i = 0 TO 5", "IF i THEN", "a = 1", "ELSE", "a = 2", "END", "END"))


def test_parser_catches_structure_mistakes(tmp_path: Path):
    bad = tmp_path / "bad.V2"
    bad.write_text(".PROGRAM bad()\n\tTYPE 1\n\n.PROGRAM other()\n.END\n")
    assert parse(bad)[1]
    bad.write_text(".PROGRAM bad()\n.END\n; stray\n")
    assert parse(bad)[1]
    bad.write_text(".PROGRAM bad()\n\tTYPE 1\n")
    assert parse(bad)[1]


# ------------------------------------------------------------------------------------------------------------
# Running the server's programs in the V+ emulator (aioadept.vplus) against aioadept.protocol: framing, parsing and
# queueing by the reader's programs, and the executor (task 1) with the simulated Viper.


def test_the_server_loads_in_the_emulator_without_problems():
    emu = Emulator.load(*FILES)
    assert emu.problems == []
    assert {"rs.main", "rs.reader", "rs.exec", "move_to", "hello"} <= set(emu.programs)


class Server:
    """The three modules loaded in an emulator (virtual time), rs.init run; a spy counts BRAKEs.

    ``extra``: more .V2 files loaded after them (a program defined again replaces the server's)."""

    def __init__(self, *extra: Path) -> None:
        self.emu = Emulator.load(*FILES, *extra, strict=True)
        self.brakes = 0
        robot = self.emu.robot
        real_brake = robot.brake

        def brake(now_s=None):
            self.brakes += 1
            return real_brake(now_s)

        robot.brake = brake
        self.emu.call("rs.init")
        # No reader task runs here (no socket): here/hello are queued like any command, not answered by it.
        self.emu.globals["rs.rdfast"] = False

    @property
    def globals(self):
        return self.emu.globals

    def call(self, name, *args, **kw):
        return self.emu.call(name, *args, **kw)


@pytest.fixture
def machine():
    return Server()


def drain(m) -> list[tuple]:
    """The command-ring entries the reader queued since the last drain, as comparable tuples."""
    g = m.globals
    out = []
    i = g["rs.qhead"]
    while i != g["rs.qtail"]:
        kind = int(g["rs.qk"][i])
        ident = g["$rs.qid"][i]
        if kind == 0:
            out.append(("error", ident, int(g["rs.qc"][i])))
        elif kind == -1:
            out.append(("stop", ident))
        else:
            n = int(g["rs.qn"][i])
            args = tuple(g["rs.qa"][i * int(g["rs.maxarg"]) + j] for j in range(n))
            out.append(("cmd", ident, g["$rs.skn"][kind], args))
        i = (i + 1) % int(g["rs.qcap"])
    g["rs.qhead"] = g["rs.qtail"]
    for k in range(int(g["rs.maxcli"])):  # drained = answered: no ID stays pending (rs.pop)
        g["rs.pout"][k] = g["rs.pin"][k]
    return out


def expected_entry(line: bytes, table: dict[str, set[int]]) -> tuple:
    """What a server built on aioadept.protocol would queue for one complete line."""
    try:
        msg = parse_command(line)
    except RemoteProtocolError as e:
        return ("error", e.id or NO_ID, int(e.code))
    if len(msg.args) > 16:
        return ("error", msg.id, int(ErrorCode.WRONG_ARGUMENT_COUNT))
    if msg.skill == STOP_SKILL:
        return ("stop", msg.id) if not msg.args else ("error", msg.id, int(ErrorCode.WRONG_ARGUMENT_COUNT))
    if msg.skill not in table:
        return ("error", msg.id, int(ErrorCode.UNKNOWN_SKILL))
    if -1 not in table[msg.skill] and len(msg.args) not in table[msg.skill]:  # -1: any count (signal, sig)
        return ("error", msg.id, int(ErrorCode.WRONG_ARGUMENT_COUNT))
    return ("cmd", msg.id, msg.skill, tuple(float(a) for a in msg.args))


def expected_stream(data: bytes, table) -> list[tuple]:
    out = []
    for item in LineFramer(128).feed(data):
        if isinstance(item, Oversize):
            out.append(("error", recover_id(item.head) or NO_ID, int(ErrorCode.LINE_TOO_LONG)))
        else:
            out.append(expected_entry(item, table))
    return out


def feed(m, data: bytes, chunks: list[int], handle: float = 7.0) -> list[tuple]:
    """Feed data as READs of the given sizes (then of 128, the most a V+ string holds) to rs.onchunk."""
    got, pos = [], 0
    sizes = iter(chunks)
    while pos < len(data):
        piece = data[pos:pos + min(next(sizes, 128), 128)]
        pos += len(piece)
        m.call("rs.onchunk", piece.decode("ascii"), handle, 0.0)
        got += drain(m)
    return got


def _close(a: tuple, b: tuple) -> bool:
    """Entries equal; command arguments equal to within REAL (single precision) rounding, as V+ stores them."""
    if a[0] == b[0] == "cmd":
        return a[:3] == b[:3] and len(a[3]) == len(b[3]) and all(
            abs(x - y) <= 1e-6 * max(1.0, abs(y)) for x, y in zip(a[3], b[3], strict=True))
    return a == b


PAPER_CHAIN = (b"eae86869:move_to:-80.000,-481.000,112.500,180.000,90.000,180.000\r\nee861124:break\r\n"
               b"3f2a0b11:set_speed:20\r\n3f2a0b12:move_rel_tool:0.000,0.000,2.500,0.000,0.000,0.000\r\n"
               b"3f2a0b13:enable_air\r\n0a000020:here\r\n0a000001:hello\r\n0a000013:stop\r\n")


def test_reader_parses_the_papers_chain_like_the_protocol_core(machine):
    table = expected_nargs()
    got = feed(machine, PAPER_CHAIN, [])
    assert got[0] == ("cmd", "eae86869", "move_to", (-80.0, -481.0, 112.5, 180.0, 90.0, 180.0))
    assert got[-1] == ("stop", "0a000013")
    want = expected_stream(PAPER_CHAIN, table)
    assert len(got) == len(want) and all(map(_close, got, want)), (got, want)
    assert machine.brakes == 1 and machine.globals["rs.stopin"] == 1


BAD_LINES = [
    b"nee861124:break", b"eae8686:break", b"eae86869", b"eae86869:", b"eae86869::break", b"eae86869:Break",
    b"eae86869:break:", b"eae86869:move_to:1,2,3,4,5", b"eae86869:move_to:1,2,,4,5,6", b"eae86869:move_to:1,2,3,4,5,6,",
    b"eae86869:move_to:1,2,3,4,5,x", b"eae86869:move_to:1e3,2,3,4,5,6", b"eae86869:nosuch", b"eae86869:break:1",
    b"eae86869:set_speed: 20 ", b"eae86869:set_speed:2 0", b"eae86869:set_speed:+.5", b"eae86869:set_speed:5.",
    b"eae86869:set_speed:.", b"eae86869:a:b:c", b"eae86869:stop:1", b":break", b"eae8686!:break",
    b"eae86869:move_to:" + b",".join([b"1"] * 20), b"eae86869:move_to:" + b",".join([b"1"] * 17) + b",x",
    b"eae86869:abcdefghijklmnop", b"eae86869:abcdefghijklmno", b"EAE86869:here", b"eae86869:here ",
    # the I/O skills: any count for signal/sig (-1 in the table), two for wait_sig, none for the hand
    b"eae86869:signal", b"eae86869:signal:1,-2,2001", b"eae86869:sig:" + b",".join([b"1"] * 17),
    b"eae86869:wait_sig:1001", b"eae86869:wait_sig:1001,2", b"eae86869:close_hand:1",
]


@pytest.mark.parametrize("line", BAD_LINES, ids=lambda b: b.decode()[:40])
def test_reader_answers_bad_lines_as_the_protocol_core(machine, line):
    got = feed(machine, line + b"\r\n", [])
    want = expected_stream(line + b"\r\n", expected_nargs())
    assert len(got) == 1 and _close(got[0], want[0]), (got, want)


def test_oversize_lines_resynchronise(machine):
    long_with_id = b"0a0b0c0d:move_to:" + b"1.000," * 30 + b"1.000"
    long_garbage = b"x" * 300
    data = long_with_id + b"\r\n" + long_garbage + b"\r\n0a000001:here\r\n" + b"y" * 129 + b"\r\n"
    for chunks in ([], [128] * 10, [1] * 40 + [50] * 20, [7, 129 - 7, 3]):
        m = Server()
        sizes = [min(c, 128) for c in chunks]
        got = feed(m, data, sizes)
        assert got == [("error", "0a0b0c0d", -402), ("error", NO_ID, -402), ("cmd", "0a000001", "here", ()),
                       ("error", NO_ID, -402)], (chunks, got)


def test_random_streams_and_splits_match_the_protocol_core(tmp_path):
    # The streams repeat IDs within one READ, which the server refuses as still pending (rs.isdup; checked over
    # TCP in tests/conformance/test_server_safety.py); parse_command alone knows no pending IDs, so here not.
    nodup = tmp_path / "nodup.V2"
    nodup.write_text(".PROGRAM rs.isdup(k, $id, dup)\n\tdup = FALSE\n.END\n")
    rng = random.Random(20260511)
    table = expected_nargs()
    good = [c for c in PAPER_CHAIN.split(b"\r\n") if c]
    for _ in range(60):
        lines = []
        for _ in range(rng.randint(1, 8)):
            r = rng.random()
            if r < 0.4:
                lines.append(rng.choice(good))
            elif r < 0.8:
                lines.append(rng.choice(BAD_LINES))
            elif r < 0.9:
                lines.append(b"%08x:move_joints:%s" % (rng.getrandbits(32), b",".join(
                    b"%.3f" % rng.uniform(-400, 400) for _ in range(6))))
            else:
                lines.append(bytes(rng.choice(b"abc:,.0123456789-") for _ in range(rng.randint(0, 200))))
        data = b"".join(line + rng.choice([b"\r\n", b"\n", b"\r\n\r\n"]) for line in lines)
        chunks = []
        while sum(chunks) < len(data):
            chunks.append(rng.randint(1, 128))
        m = Server(nodup)
        got = feed(m, data, chunks)
        want = expected_stream(data, table)
        assert len(got) == len(want) and all(map(_close, got, want)), (data, chunks, got, want)


def test_disconnect_discards_queued_commands(machine):
    m = machine
    feed(m, b"0a000001:here\r\n", [], handle=3.0)
    m.globals["rs.qhead"] = 0          # keep the entry queued, as if task 1 were busy
    slot = int(m.globals["rs.qs"][0])
    assert m.globals["rs.qg"][0] == m.globals["rs.cgen"][slot]
    m.call("rs.ondisc", 3.0, 0.0)
    assert m.globals["rs.qg"][0] != m.globals["rs.cgen"][slot], "task 1 would still run it"
    m.call("rs.onconn", 3.0, 0.0)           # a new client with the same handle gets a new generation too
    assert m.globals["rs.qg"][0] != m.globals["rs.cgen"][slot]


@pytest.mark.parametrize("x", [0, 7, -7, 10, -300, -401, -1003, -1200, 123456])
def test_itoa(machine, x):
    assert machine.call("rs.itoa", float(x), "").args[1] == str(x)


@pytest.mark.parametrize("text", ["*Joint 1 limit* : at step 3", "a::b", "", "x" * 100, ":lead", "trail:"])
def test_clean_makes_an_ack_field(machine, text):
    s = machine.call("rs.clean", text, "").args[1]
    assert ":" not in s and len(s) <= 60 and s.replace(";", "") == text.replace(":", "")[:len(s.replace(";", ""))]


# -- the executor (task 1) in the interpreter: acks, refusals, stop --------------------------------------------


def queue(m, data: bytes, handle: float = 7.0) -> None:
    """Task 2 reads data (READs of up to 128 characters) and queues entries; nothing is drained."""
    for pos in range(0, len(data), 128):
        m.call("rs.onchunk", data[pos:pos + 128].decode("ascii"), handle, 0.0)


def run_queue(m) -> list:
    """Let task 1 (robot attached) take every queued entry (rs.step), then return the acks the reader would write."""
    g = m.globals
    while g["rs.qhead"] != g["rs.qtail"]:
        m.call("rs.step", task=1, attach=True)
    return take_acks(m)


def take_acks(m) -> list:
    g = m.globals
    acks = []
    i = g["rs.ohead"]
    while i != g["rs.otail"]:
        line = (g["$rs.oa"][i] + g["$rs.ob"][i]).encode("ascii")
        acks.append(parse_ack(line))
        i = (i + 1) % int(g["rs.ocap"])
    g["rs.ohead"] = g["rs.otail"]
    return acks


def test_executor_acks_parse_and_carry_the_pose(machine):
    home = machine.emu.controller.here_at(0.0)
    queue(machine, PAPER_CHAIN.replace(b"0a000013:stop\r\n", b""))
    acks = run_queue(machine)
    assert [a.id for a in acks] == ["eae86869", "ee861124", "3f2a0b11", "3f2a0b12", "3f2a0b13", "0a000020",
                                    "0a000001"]
    assert all(a.status is Status.DONE for a in acks), acks
    # forward processing: the move acks at once with the pose where the motion started; break when it is done
    assert acks[0].pose.x == pytest.approx(home.x, abs=1e-3) and acks[0].t_done_s == 0.0
    assert acks[1].t_done_s > 0.1
    assert (acks[1].pose.x, acks[1].pose.y, acks[1].pose.z) == pytest.approx((-80.0, -481.0, 112.5), abs=2e-3)
    assert acks[-1].extra == (str(PROTOCOL_VERSION), "aioadept-vplus 0.1.0")
    assert machine.emu.signals.get(8) is True                       # enable_air: SIGNAL rs.airsig
    assert machine.emu.controller.always_speed_pct == 100.0


def test_executor_refusals_are_error_acks_without_motion(machine):
    m = machine
    queue(m, b"00000001:set_speed:101\r\n00000002:move_joints:0,-90,300,0,90,0\r\n00000003:nosuch\r\n")
    queue(m, b"00000004:move_to:1000,0,0,0,180,0\r\n00000005:move_rel_joints:0,0,0,0,200,0\r\n")
    joints = m.emu.controller.joints_at(0.0)
    acks = run_queue(m)
    assert [(a.id, a.status, a.error_code) for a in acks] == [
        ("00000001", Status.ERROR, ErrorCode.ILLEGAL_VALUE), ("00000002", Status.ERROR, ErrorCode.JOINT_LIMIT),
        ("00000003", Status.ERROR, ErrorCode.UNKNOWN_SKILL), ("00000004", Status.ERROR, ErrorCode.OUT_OF_REACH),
        ("00000005", Status.ERROR, ErrorCode.JOINT_LIMIT)]
    assert [a.error_message for a in acks][:2] == ["speed outside 1..100", "joint limit"]
    ctl = m.emu.controller
    assert ctl.joints_at(m.emu.time_s + 10) == joints and ctl.pending_speed_pct is None, "a refused skill moved"


def test_stop_during_break_aborts_in_order_then_acks_done(machine):
    """docs/protocol.md 4.2: the waiting break and the queued commands aborted, then the stop done."""
    m = machine
    queue(m, b"0a000010:move_rel_tool:0.000,0.000,50.000,0.000,0.000,0.000\r\n0a000011:break\r\n"
            b"0a000012:set_speed:5\r\n")
    m.call("rs.step", task=1, attach=True)               # the move: acked done at once (forward processing)
    m.emu.robot.attach(1)
    t1 = m.emu.execute(1, "rs.step")                      # the break: task 1 waits for the motion
    t1.robot_attached = True
    m.emu.run(0.02)
    assert t1.state == "running" and m.emu.controller.trajectory.in_motion(m.emu.time_s)
    queue(m, b"0a000013:stop\r\n0a000014:here\r\n", handle=7.0)   # task 2 reads the stop meanwhile (BRAKE)
    m.emu.run(until=lambda: t1.state != "running")
    acks = run_queue(m)
    assert [(a.id, a.status) for a in acks] == [
        ("0a000010", Status.DONE), ("0a000011", Status.ABORTED), ("0a000012", Status.ABORTED),
        ("0a000013", Status.DONE), ("0a000014", Status.DONE)]
    assert m.brakes >= 2 and m.emu.controller.pending_speed_pct is None
    assert not m.emu.controller.trajectory.in_motion(m.emu.time_s)
    assert m.globals["rs.stopin"] == m.globals["rs.stopout"] == 1


def test_stop_with_nothing_to_abort_is_done_at_once(machine):
    queue(machine, b"0a000013:stop\r\n")
    assert [(a.id, a.status) for a in run_queue(machine)] == [("0a000013", Status.DONE)]


def test_gone_client_commands_never_run(machine):
    m = machine
    queue(m, b"0b000001:enable_air\r\n", handle=3.0)
    queue(m, b"0b000002:here\r\n", handle=4.0)
    m.call("rs.ondisc", 3.0, 0.0)
    acks = run_queue(m)
    assert [a.id for a in acks] == ["0b000002"]
    assert not m.emu.signals.get(8)


def test_v_plus_error_in_a_skill_becomes_an_error_ack(machine):
    """REACTE rs.onerr: a robot error in a skill answers -300 with the V+ code, and the next command runs."""
    m = machine
    m.globals["rs.chkrange"] = False          # no INRANGE check: the MOVE itself fails
    queue(m, b"0c000001:move_to:1500,0,500,0,180,0\r\n0c000002:here\r\n")
    acks = run_queue(m)
    assert [(a.id, a.status) for a in acks] == [("0c000001", Status.ERROR), ("0c000002", Status.DONE)]
    assert acks[0].error_code == ErrorCode.SKILL_FAILED
    assert acks[0].error_message.startswith("V+ -610 ") and ":" not in acks[0].error_message


def test_the_ports_in_rsconfig_are_the_python_defaults():
    """The client, ``aioadept state`` and the cell file find the shipped V+ server where rsconfig.V2 puts it: the
    command port, the stop port and the state stream's port (these once disagreed: the state port default was the
    stop port)."""
    from aioadept import defaults

    text = (VPLUS / "rsconfig.V2").read_text()

    def value(name: str) -> int:
        (line,) = [ln for ln in text.splitlines() if ln.strip().startswith(f"{name} = ")]
        return int(line.split("=", 1)[1].split(";")[0])

    assert (value("rs.port"), value("rs.sport"), value("rs.stport")) == (
        defaults.ROBOT_PORT, defaults.STOP_PORT, defaults.STATE_STREAM_PORT)
