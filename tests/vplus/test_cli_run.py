"""``aioadept sim --vplus ... --run P`` never hangs silently: a program that stops or fails before
it opens its socket is reported in one line and the process exits non-zero; a program that calls one no loaded
file defines is named. Real child processes, each with a hard timeout."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

VPLUS = Path(__file__).resolve().parents[2] / "vplus"


def sim(*args: str, timeout: float = 30.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "aioadept", "sim", "--instant", *args], capture_output=True,
                          text=True, timeout=timeout)


def write(tmp_path: Path, text: str) -> str:
    p = tmp_path / "prog.V2"
    p.write_text(text)
    return str(p)


@pytest.mark.timeout(60)
def test_a_program_failing_before_its_socket_is_reported_and_exits_non_zero(tmp_path):
    f = write(tmp_path, '.PROGRAM main()\n\tTYPE "starting"\n\tx = 1/0\n\tATTACH (lun, 4) "TCP"\n.END\n')
    res = sim("--vplus", f, "--run", "main")
    assert res.returncode == 1
    assert "READY" not in res.stdout and "[0] starting" in res.stdout
    err = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(err) == 1 and "main stopped before it opened a socket" in err[0] and "Division by 0" in err[0]
    assert "Traceback" not in res.stderr


@pytest.mark.timeout(60)
def test_a_program_ending_without_a_socket_exits_non_zero(tmp_path):
    f = write(tmp_path, '.PROGRAM main()\n\tTYPE "nothing to serve"\n.END\n')
    res = sim("--vplus", f, "--run", "main")
    assert res.returncode == 1 and "ended before it opened a socket" in res.stderr


@pytest.mark.timeout(60)
def test_the_server_without_its_skills_module_names_the_missing_program(tmp_path):
    # rserver.V2 without rsskills.V2: rs.init calls the skill hello to copy its version
    res = sim("--vplus", str(VPLUS / "rserver.V2"), str(VPLUS / "rsconfig.V2"), "--run", "rs.main",
              "--map-port", "1234=0", "--map-port", "1235=0")
    assert res.returncode == 1
    err = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(err) == 1 and "*Undefined program or variable name* hello" in err[0]
    assert "no loaded file defines hello (load its module too)" in err[0]


@pytest.mark.timeout(60)
def test_run_of_a_program_no_file_defines_is_one_line(tmp_path):
    f = write(tmp_path, ".PROGRAM main()\n.END\n")
    res = sim("--vplus", f, "--run", "mian")
    assert res.returncode == 2 and res.stderr.strip().count("\n") == 0 and "mian" in res.stderr


@pytest.mark.timeout(60)
def test_a_disk_option_names_the_folder_of_the_programs_files(tmp_path):
    f = write(tmp_path, '.PROGRAM main()\n\tATTACH (d, 4) "DISK"\n\tFOPENW (d) "out.txt"\n\tWRITE (d) "hi"\n'
                        '\tFCLOSE (d)\n.END\n')
    res = sim("--vplus", f, "--run", "main", "--disk", str(tmp_path / "disk"))
    assert (tmp_path / "disk" / "out.txt").read_bytes() == b"hi\r\n"
    assert res.returncode == 1 and "ended before it opened a socket" in res.stderr
    bad = sim("--vplus", f, "--run", "main", "--disk", f)
    assert bad.returncode == 2 and "not a folder" in bad.stderr and "Traceback" not in bad.stderr
