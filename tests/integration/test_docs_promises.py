"""Every promise of the documentation site (docs/*.md) holds, checked by running what the pages print.

1. Each ```python block runs doctest-style in a fresh folder (top-level ``await`` allowed, as in a notebook).
2. Each shell line of a ```sh/```console/```bash block that starts with ``aioadept`` or ``.venv/bin/aioadept`` runs as
   a subprocess: exit status 0 (or the ``exit status N`` its comment states), and every output line the page shows
   (console lines without ``$``, or a ``# prints ...`` comment) is produced. A server line (``sim``/``vision``
   serving) is started, its READY line compared with the page and then stopped with SIGINT; a line ending in ``&``
   stays up until the block's ``kill %1``. Documented ports are used as printed when they are free, else the page's
   block is skipped with the reason. ``runs/NAME`` folders a block reads are made first from synthetic runs.
3. Each ``--option`` written next to ``aioadept SUBCOMMAND`` (in a code block line or an inline code span) is in
   that subcommand's ``--help``.

A block that cannot run standalone (a fragment, a real robot or network, minutes of run time) carries
``<!-- not-run: reason -->`` on the line before its fence; those blocks are skipped with that reason (``-rs`` lists
them) and counted by ``test_not_run_blocks_say_why``. The blocks of one page share one folder and run in page order.
"""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
AIOADEPT = Path(sys.executable).with_name("aioadept")
NOT_RUN = re.compile(r"^<!--\s*not-run:\s*(.*?)\s*-->\s*$")
FENCE = re.compile(r"^```(\w+)\s*\n(.*?)^```\s*$", re.S | re.M)
SHELL_LANGS = {"sh", "console", "bash", "shell"}
CLI = re.compile(r"^(?:\.venv/bin/)?aioadept(?:\s|$)")

# Runs `sys.stdin` as a notebook cell would: top-level `await` allowed (the block is then run by asyncio.run).
RUNNER = """
import ast, asyncio, sys
name = sys.argv[1]
code = compile(sys.stdin.read(), name, "exec", flags=ast.PyCF_ALLOW_TOP_LEVEL_AWAIT)
result = eval(code, {"__name__": "__main__"})
if asyncio.iscoroutine(result):
    asyncio.run(result)
"""


@dataclass(frozen=True)
class Block:
    page: str
    line: int  # line of the opening fence, 1-based
    lang: str
    code: str
    not_run: str | None

    @property
    def name(self) -> str:
        return f"{self.page}:{self.line}"


def _blocks() -> list[Block]:
    blocks = []
    for path in sorted(DOCS.glob("*.md")):
        text = path.read_text()
        for m in FENCE.finditer(text):
            before = text[: m.start()].rstrip("\n").splitlines()
            reason = NOT_RUN.match(before[-1]) if before else None
            blocks.append(Block(path.name, text[: m.start()].count("\n") + 1, m.group(1), m.group(2),
                                reason.group(1) if reason else None))
    return blocks


BLOCKS = _blocks()


@dataclass
class Command:
    argv: str  # the command as printed, without `$ ` and comment
    comment: str
    shown: list[str]  # output lines the page shows for it


def _commands(block: Block) -> list[Command]:
    """The block's shell commands, `\\` continuations joined; console output lines attached to their command."""
    cmds: list[Command] = []
    pending = ""
    for raw in block.code.splitlines():
        line = raw.rstrip()
        if block.lang == "console" and not line.startswith("$ ") and not pending:
            if cmds and line.strip() and not line.startswith("#"):
                cmds[-1].shown.append(line.strip())
            continue
        line = line[2:] if line.startswith("$ ") else line
        if line.endswith("\\"):
            pending += line[:-1] + " "
            continue
        line, pending = pending + line, ""
        cmd, _, comment = line.partition(" #")
        if cmd.strip() and not cmd.lstrip().startswith("#"):
            cmds.append(Command(cmd.strip(), comment.strip(), []))
    if block.lang != "console":
        for c in cmds:  # `# prints X ... when it listens`: the text after `prints` up to a lower-case tail
            m = re.match(r"prints:? (.*?)(?: when .*)?$", c.comment)
            if m:
                c.shown.append(m.group(1).strip())
    return cmds


def _page_blocks(page: str) -> list[Block]:
    return [b for b in BLOCKS if b.page == page and
            (b.lang == "python" or (b.lang in SHELL_LANGS and any(CLI.match(c.argv) for c in _commands(b))))]


PAGES = sorted({b.page for b in BLOCKS if _page_blocks(b.page)})


def _port_free(port: int) -> bool:
    with socket.socket() as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def _shown_matches(shown: str, output: str, argv: str) -> bool:
    pattern = re.escape(shown).replace(re.escape("..."), ".*")
    if re.search(r"--port 0\b", argv):  # an ephemeral port: the number printed is an example
        pattern = re.sub(r"port=\d+", r"port=\\d+", pattern)
    return re.search(pattern, output) is not None


def _make_runs(paths: set[str], cwd: Path) -> None:
    """Synthetic run folders for the `runs/NAME` paths a page reads."""
    from aioadept.analysis.synthetic import synthetic_recorder

    for i, rel in enumerate(sorted(paths)):
        if not (cwd / rel).exists():
            rec, params = synthetic_recorder(seed=i, approach_speed=25, delta_z_mm=2.0, n_steps=8)
            rec.save(cwd / rel, metadata=params)


def _serving(argv: list[str]) -> bool:
    """A subcommand that serves until stopped (sim, and vision unless it makes figures or prints help)."""
    return argv[1] in ("sim", "vision") and not {"--help", "-h", "--figures", "--graph"} & set(argv)


def _start_server(argv: list[str], cwd: Path, env: dict) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    ready = proc.stdout.readline()  # the handshake: the server prints READY when it listens (or exits)
    assert ready.startswith("READY"), f"{' '.join(argv)}: {ready!r} {proc.stderr.read() if proc.poll() else ''}"
    return proc, ready


def _stop(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        raise AssertionError("the server did not stop on SIGINT within 10 s") from None


def _run_shell_block(block: Block, cwd: Path, env: dict) -> None:
    background: list[subprocess.Popen] = []
    try:
        for cmd in _commands(block):
            if cmd.argv.startswith("kill %"):
                for proc in background:
                    _stop(proc)
                background.clear()
                continue
            if not CLI.match(cmd.argv):
                continue
            text = cmd.argv.rstrip("&").strip()
            argv = [str(AIOADEPT)] + text.split()[1:]
            where = f"{block.name}: {cmd.argv}"
            if _serving(argv):
                proc, output = _start_server(argv, cwd, env)
                for shown in cmd.shown:
                    assert _shown_matches(shown, output, text), f"{where}: page shows {shown!r}, got {output!r}"
                if cmd.argv.endswith("&"):
                    background.append(proc)
                else:
                    _stop(proc)
                continue
            expected = re.search(r"exit status (\d+)", cmd.comment)
            proc = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=40)
            assert proc.returncode == (int(expected.group(1)) if expected else 0), \
                f"{where}: exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
            assert "Traceback" not in proc.stderr, f"{where}:\n{proc.stderr}"
            for shown in cmd.shown:
                assert _shown_matches(shown, proc.stdout + proc.stderr, text), f"{where}: page shows {shown!r}"
            # where the outputs go: `--out DIR`, or the comment's `outputs go into DIR`
            out = re.search(r"--out (\S+)", text) or re.search(r"outputs go into (\S+)", cmd.comment)
            if out:
                assert (cwd / out.group(1) / "summary.json").is_file(), f"{where}: no summary.json in {out.group(1)}"
    finally:
        for proc in background:
            proc.kill()
            proc.wait()


def _documented_ports(block: Block) -> set[int]:
    ports = set()
    for cmd in _commands(block):
        if CLI.match(cmd.argv) and _serving(["aioadept"] + cmd.argv.split()[1:]):
            m = re.search(r"--port (\d+)", cmd.argv)
            port = int(m.group(1)) if m else 1234
            if port:
                ports.add(port)
            if "--state-endpoint" not in cmd.argv and cmd.argv.split()[1] == "sim":
                ports.add(5560)  # the sim's default state stream
    return ports


def _run_pytest_block(block: Block, cwd: Path, env: dict) -> None:
    """A block that is a test file (first line `# tests/test_X.py`) is written there and run with pytest: the
    repository's vplus/ is linked in, and a V+ file of yours it loads (`my_skills.V2`) is an empty program."""
    rel = re.match(r"# (\S+)", block.code).group(1)
    (cwd / rel).parent.mkdir(parents=True, exist_ok=True)
    (cwd / rel).write_text(block.code)
    (cwd / "vplus").symlink_to(ROOT / "vplus")
    for name in set(re.findall(r'"([\w/]+\.V2)"', block.code)):
        if not (cwd / name).exists():
            (cwd / name).write_text(".PROGRAM my.noop()\n.END\n")
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", rel], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=50)
    assert proc.returncode == 0 and " passed" in proc.stdout, f"{block.name}:\n{proc.stdout}\n{proc.stderr}"


@pytest.mark.timeout(30)
def test_the_docs_have_runnable_blocks():
    runnable = [b for p in PAGES for b in _page_blocks(p) if b.not_run is None]
    assert sum(b.lang == "python" for b in runnable) >= 4
    assert sum(b.lang in SHELL_LANGS for b in runnable) >= 3


@pytest.mark.timeout(60)
@pytest.mark.parametrize("page", PAGES)
def test_each_page_runs_as_printed(page, tmp_path):
    """The page's python blocks and aioadept shell lines, in page order, in one fresh folder."""
    blocks = _page_blocks(page)
    runnable = [b for b in blocks if b.not_run is None]
    if not runnable:
        pytest.skip("; ".join(f"{b.name}: {b.not_run}" for b in blocks))
    busy = sorted(p for b in runnable for p in _documented_ports(b) if not _port_free(p))
    if busy:
        pytest.skip(f"documented port(s) {busy} in use on this machine")
    _make_runs({m for b in runnable if b.lang in SHELL_LANGS or b.lang == "python"
                for m in re.findall(r"\bruns/[\w.-]+", b.code)}, tmp_path)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "MPLBACKEND": "Agg"}
    for block in runnable:
        if block.lang == "python" and re.match(r"# (tests/test_\w+\.py)\n", block.code):
            _run_pytest_block(block, tmp_path, env)
        elif block.lang == "python":
            proc = subprocess.run([sys.executable, "-c", RUNNER, block.name], input=block.code, cwd=tmp_path,
                                  env=env, capture_output=True, text=True, timeout=50)
            assert proc.returncode == 0, f"{block.name}:\n{proc.stderr}"
        else:
            _run_shell_block(block, tmp_path, env)


@pytest.mark.timeout(30)
def test_not_run_blocks_say_why(capsys):
    """Every not-run marker sits on a code block with something to run and gives a reason; the tally is printed."""
    skipped = [b for p in PAGES for b in _page_blocks(p) if b.not_run is not None]
    for b in skipped:
        assert len(b.not_run.split()) >= 3, f"{b.name}: say why it cannot run"
    for path in DOCS.glob("*.md"):
        lines = path.read_text().splitlines()
        for i, line in enumerate(lines):
            if NOT_RUN.match(line):
                assert i + 1 < len(lines) and lines[i + 1].startswith("```"), \
                    f"{path.name}:{i + 1}: a not-run marker must be right above a code fence"
    with capsys.disabled():
        print(f"\ndocs blocks not run: {len(skipped)}")
        for b in skipped:
            print(f"  {b.name} [{b.lang}]: {b.not_run}")


# --- 3. every documented option exists --------------------------------------------------------------------------

def _subcommands() -> list[str]:
    from aioadept.cli import SUBCOMMANDS

    return sorted(SUBCOMMANDS)


def _option_mentions() -> list[tuple[str, str, str]]:
    """(page:line, subcommand, --option) for each option written after `aioadept SUB` in a code line or span."""
    subs = "|".join(_subcommands())
    mentions = []
    for path in sorted(DOCS.glob("*.md")):
        text = path.read_text()
        spans = []  # (offset, text) of code-block command lines and inline code spans
        for m in FENCE.finditer(text):
            if m.group(1) in SHELL_LANGS or m.group(1) == "text":
                block = Block(path.name, 0, m.group(1), m.group(2), None)
                offset = m.start(2)
                for cmd in _commands(block):
                    spans.append((offset, cmd.argv))
        prose = FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), text)
        spans += [(m.start(), m.group(1)) for m in re.finditer(r"`([^`\n]+)`", prose)]
        for offset, span in spans:
            for m in re.finditer(rf"\baioadept ({subs})\b(.*)|make (demo) ARGS=(.*)", span):
                sub, rest = (m.group(1), m.group(2)) if m.group(1) else (m.group(3), m.group(4))
                line = text[:offset].count("\n") + 1
                for opt in re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", rest):
                    mentions.append((f"{path.name}:{line}", sub, opt))
        if path.name in PAGE_SUBCOMMAND:  # the guide's option table: `--opt` in a row's first column
            for m in re.finditer(r"^\|\s*`(--[a-z][a-z0-9-]*)", text, re.M):
                mentions.append((f"{path.name}:{text[:m.start()].count(chr(10)) + 1}", PAGE_SUBCOMMAND[path.name],
                                 m.group(1)))
    return mentions


PAGE_SUBCOMMAND = {"sim.md": "sim", "vision.md": "vision", "focus.md": "focus", "analysis.md": "analyze"}


@pytest.mark.timeout(60)
def test_every_documented_option_is_in_its_subcommands_help():
    mentions = _option_mentions()
    assert len(mentions) > 30, mentions
    subs = sorted({sub for _, sub, _ in mentions})
    procs = {sub: subprocess.Popen([str(AIOADEPT), sub, "--help"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                   text=True) for sub in subs}
    helps = {}
    for sub, proc in procs.items():
        out, err = proc.communicate(timeout=40)
        assert proc.returncode == 0, f"aioadept {sub} --help: {err}"
        helps[sub] = set(re.findall(r"(?<![\w-])--[a-z][a-z0-9-]*", out))
    missing = [f"{where}: aioadept {sub} {opt}" for where, sub, opt in mentions if opt not in helps[sub]]
    assert not missing, "options the docs name that --help does not have:\n" + "\n".join(missing)


# --- interfaces.md: the documented record fields are the classes' fields ------------------------------------------

@pytest.mark.timeout(30)
@pytest.mark.parametrize("cls_path", ["aioadept.client.results.SentMessage", "aioadept.client.results.MessageResult",
                                      "aioadept.bus.pairing.Request", "aioadept.bus.pairing.Response"])
def test_interfaces_page_lists_each_records_fields(cls_path):
    import dataclasses
    import importlib

    module, name = cls_path.rsplit(".", 1)
    cls = getattr(importlib.import_module(module), name)
    text = (DOCS / "interfaces.md").read_text()
    line = re.search(rf"^class {name}:\s*(.*)$", text, re.M).group(1)
    documented = [field.split(":")[0].strip() for field in line.split(";")]
    assert documented == [f.name for f in dataclasses.fields(cls)], f"interfaces.md: {name}"
