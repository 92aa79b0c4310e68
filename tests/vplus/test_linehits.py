"""The emulator's own line recorder (aioadept.vplus.linehits): which .V2 lines ran, in this process and in an
``aioadept sim --vplus`` started with AIOADEPT_VPLUS_LINES, and the report ``make test`` prints."""

from __future__ import annotations

import os
import subprocess
import sys

from aioadept.vplus import Emulator, linehits

PROG = (".PROGRAM t.main(n)\n"         # 1
        "; which branch runs depends on n\n"  # 2
        "    AUTO i\n"                  # 3  a declaration: not a line to run
        "    i = 0\n"                   # 4
        "    IF n > 0 THEN\n"           # 5
        "        i = 1\n"               # 6
        "    ELSE\n"                    # 7
        "        i = 2\n"               # 8
        "    END\n"                     # 9
        "    CALL t.never()\n"          # 10
        ".END\n"                        # 11
        ".PROGRAM t.never()\n"          # 12
        "    IF FALSE THEN\n"           # 13
        "        TYPE \"no\"\n"         # 14
        "    END\n"                     # 15
        ".END\n"                        # 16
        ".PROGRAM t.run()\n"            # 17
        "    CALL t.main(0)\n"          # 18
        ".END\n")


def test_the_recorder_reports_the_lines_that_ran_and_the_executable_lines_that_did_not(tmp_path):
    path = tmp_path / "t.V2"
    path.write_text(PROG)
    emu = Emulator.load(path, robot=False, strict=True)
    rec = linehits.attach(emu.rt)
    emu.call("t.main", 1)
    assert rec.hits == {(str(path), n) for n in (4, 5, 6, 10, 13)}
    # a second runtime sharing the hits hooks only the lines not run yet; a run of the other branch adds line 8
    emu2 = Emulator.load(path, robot=False, strict=True)
    linehits.attach(emu2.rt, rec.hits)
    assert emu2.rt.trace_lines("t.main") & {4, 5, 6, 8, 10} == {8}
    emu2.call("t.main", 0)
    [(name, stmts, ran, missed)] = linehits.report({str(path): {p[1] for p in rec.hits}}, [path])
    assert (name, stmts, ran, missed) == (str(path), 8, 6, {14, 18})
    table = linehits.table(linehits.report({}, [path]), tmp_path).splitlines()
    assert table[2].split() == ["t.V2", "8", "8", "0%", "4-6,", "8,", "10,", "13-14,", "18"]
    assert table[-1].split() == ["TOTAL", "8", "8", "0%"]


def test_an_emulated_server_started_with_the_variable_writes_its_lines_when_it_ends(tmp_path):
    path = tmp_path / "t.V2"
    path.write_text(PROG)
    folder = tmp_path / "lines"
    folder.mkdir()
    env = {**os.environ, linehits.ENV: str(folder)}
    # the program ends without opening a socket: the server ends (status 1) and saves what ran
    r = subprocess.run([sys.executable, "-m", "aioadept", "sim", "--vplus", str(path), "--run", "t.run",
                        "--instant", "--state-endpoint", "none"], env=env, capture_output=True, text=True,
                       timeout=60)
    assert "ended before it opened a socket" in r.stderr, r.stderr
    assert linehits.load(folder) == {str(path): {18, 4, 5, 8, 10, 13}}
    # without the variable nothing is written
    env.pop(linehits.ENV)
    subprocess.run([sys.executable, "-m", "aioadept", "sim", "--vplus", str(path), "--run", "t.run",
                    "--instant", "--state-endpoint", "none"], env=env, capture_output=True, timeout=60)
    assert len(list(folder.iterdir())) == 1


def test_the_recorder_keeps_the_auto_variables_python_locals_as_without_a_tracer(tmp_path):
    path = tmp_path / "t.V2"
    path.write_text(PROG)
    emu = Emulator.load(path, robot=False, strict=True)
    linehits.attach(emu.rt)
    code = emu.rt.programs["t.main"].__code__
    assert "V_i" in code.co_varnames and "_dbg" in code.co_names      # a local, and the line hook
    emu.call("t.main", 1)
    # a debugger's tracer still has them in L, where it reads and sets them
    emu2 = Emulator.load(path, robot=False, strict=True)
    emu2.rt.set_tracer(linehits.LineRecorder(emu2.rt))
    assert "V_i" not in emu2.rt.programs["t.main"].__code__.co_varnames
