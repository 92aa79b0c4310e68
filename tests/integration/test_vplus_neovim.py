"""A real editor as the V+ language server's client: headless Neovim (its built-in LSP client) opens a copy of
vplus/rserver.V2 with a planted mistake, starts ``aioadept vplus lsp`` and reads back the diagnostic and a go to
definition into another module of the folder (tests/integration/nvim_vplus_lsp.lua).

Neovim is Debian's ``neovim`` (``make test`` installs it where it runs as root with apt-get: the Makefile's
``nvim`` target); where there is no ``nvim`` the test is skipped with a warning saying so."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = Path(__file__).resolve().parent / "nvim_vplus_lsp.lua"


@pytest.mark.timeout(60)
def test_neovim_shows_the_planted_mistake_and_goes_to_a_definition_in_another_module(tmp_path):
    nvim = shutil.which("nvim")
    if nvim is None:
        reason = ("NEOVIM LSP TEST NOT RUN: no nvim on PATH (Debian: apt-get install neovim; "
                  "make test does it as root)")
        warnings.warn(reason, stacklevel=1)
        pytest.skip(reason)
    for name in ("rserver.V2", "rsskills.V2", "rsstate.V2", "rsconfig.V2"):
        shutil.copyfile(ROOT / "vplus" / name, tmp_path / name)
    server = tmp_path / "rserver.V2"
    lines = server.read_text("latin-1").split("\n")
    # the planted mistake: a GOTO to a label the program does not have, after rs.main's first statement
    main = next(i for i, line in enumerate(lines) if line.upper().startswith(".PROGRAM RS.MAIN("))
    first = next(i for i in range(main + 1, len(lines)) if lines[i].strip() and not lines[i].strip().startswith(";"))
    lines.insert(first, "\tGOTO 4242")
    # a CALL of a program that rsconfig.V2 (another module) defines
    call = next(i for i, line in enumerate(lines) if line.strip().upper().startswith("CALL RS.CONFIG"))
    server.write_text("\n".join(lines), "latin-1")
    out = tmp_path / "out.json"
    env = dict(os.environ, VPLUS_FILE=str(server), VPLUS_OUT=str(out), VPLUS_LINE=str(call),
               VPLUS_COL=str(lines[call].upper().index("RS.CONFIG") + 3),
               VPLUS_CMD=json.dumps([sys.executable, "-m", "aioadept.cli", "vplus", "lsp"]))
    proc = subprocess.run([nvim, "--headless", "--clean", "-c", f"luafile {SCRIPT}"], env=env, cwd=tmp_path,
                          capture_output=True, text=True, timeout=50)
    assert out.exists(), f"nvim wrote nothing (exit {proc.returncode}):\n{proc.stdout}\n{proc.stderr}"
    got = json.loads(out.read_text())
    assert "error" not in got, got
    errors = [d for d in got["diagnostics"] if d["severity"] == 1]     # warnings may come too
    assert errors == [{"lnum": first, "col": 6, "end_col": 10, "severity": 1,
                                   "source": "aioadept vplus",
                                   "message": errors[0]["message"]}], got
    assert "undefined label 4242" in errors[0]["message"]
    config_line = next(i for i, line in enumerate((tmp_path / "rsconfig.V2").read_text("latin-1").split("\n"))
                       if line.upper().startswith(".PROGRAM RS.CONFIG("))
    assert got["definition"] == [[{"uri": (tmp_path / "rsconfig.V2").as_uri(),
                                   "range": {"start": {"line": config_line, "character": 9},
                                             "end": {"line": config_line, "character": 18}}}]], got
