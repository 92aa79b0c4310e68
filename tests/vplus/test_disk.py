"""Disk files: FOPENR/FOPENW/FOPENA/FOPEND, READ/WRITE/FCLOSE on disk LUNs, FDELETE, IOSTAT,
on real files in a folder the user names, and nothing outside it."""

from __future__ import annotations

import os

import pytest

from aioadept.vplus import Emulator
from aioadept.vplus import errors as E


def disk_emu(tmp_path, body: str) -> Emulator:
    emu = Emulator.from_source(".PROGRAM t()\n\tATTACH (dl, 4) \"DISK\"\n" + body + "\n.END\n", filename="d.V2",
                               strict=True, robot=False, disk_dir=tmp_path / "disk")
    emu.call("t")
    return emu


def test_write_append_then_read_records_to_the_end_of_file(tmp_path):
    g = disk_emu(tmp_path, """
\tFOPENW (dl) "log.txt"
\tw1 = IOSTAT(dl)
\tWRITE (dl) "pick ", 3
\tWRITE (dl) "place"
\tFCLOSE (dl)
\tFOPENW (dl) "log.txt"
\tw2 = IOSTAT(dl)
\tFOPENA (dl) "C:log.txt"
\tWRITE (dl) "done"
\tFCLOSE (dl)
\tFOPENR (dl) "log.txt"
\tn = 0
\tREAD (dl) $r
\tWHILE IOSTAT(dl) == 1 DO
\t\t$rec[n] = $r
\t\tn = n+1
\t\tREAD (dl) $r
\tEND
\teof = IOSTAT(dl)
\tFCLOSE (dl)
""").globals
    assert (tmp_path / "disk" / "log.txt").read_bytes() == b"pick 3\r\nplace\r\ndone\r\n"
    assert g["w1"] == 1 and g["w2"] == E.FILE_EXISTS            # FOPENW of a file that exists
    assert g["n"] == 3 and g["$rec"] == {0: "pick 3", 1: "place", 2: "done"} and g["eof"] == E.END_OF_FILE


def test_reading_a_file_the_user_put_there_and_deleting_it(tmp_path):
    (tmp_path / "disk" / "parts").mkdir(parents=True)
    (tmp_path / "disk" / "parts" / "list.dat").write_bytes(b"a1\nb2\r\n")
    g = disk_emu(tmp_path, """
\tFOPENR (dl) "\\\\parts\\\\list.dat"
\tREAD (dl) $a
\tREAD (dl) $b
\tFCLOSE (dl)
\tFOPENR (dl) "nothere.dat"
\tmissing = IOSTAT(dl)
\tFDELETE (dl) "parts\\\\list.dat"
\tdel = IOSTAT(dl)
\tFOPEND (dl) "parts\\\\"
\tREAD (dl) $d
\tnd = IOSTAT(dl)
\tFCLOSE (dl)
\tFOPENW (dl) "longname9.txt"
\tlong = IOSTAT(dl)
\tFOPENW (dl) "name.text"
\tlongext = IOSTAT(dl)
""").globals
    assert (g["$a"], g["$b"]) == ("a1", "b2")
    assert g["missing"] == E.NONEXISTENT_FILE and g["del"] == 1
    assert not (tmp_path / "disk" / "parts" / "list.dat").exists()
    assert g["nd"] == E.END_OF_FILE          # the folder is empty now: the directory read ends at once
    assert g["long"] == g["longext"] == E.ILLEGAL_FILE_NAME        # names are 8.3 (User's Guide p. 216)
    assert sorted(p.name for p in (tmp_path / "disk").iterdir()) == ["parts"]


@pytest.mark.parametrize("spec", ["..\\\\secret.txt", "sub\\\\..\\\\..\\\\secret.txt", "/etc/passwd", "link\\\\secret.txt",
                                  "out.txt"])
def test_a_path_leaving_the_folder_is_refused_and_touches_nothing(tmp_path, spec):
    outside = tmp_path / "secret.txt"
    outside.write_text("keep")
    (tmp_path / "disk").mkdir()
    os.symlink(tmp_path, tmp_path / "disk" / "link")
    os.symlink(outside, tmp_path / "disk" / "out.txt")
    g = disk_emu(tmp_path, f"""
\tFOPENR (dl) "{spec}"
\tr = IOSTAT(dl)
\tFOPENA (dl) "{spec}"
\ta = IOSTAT(dl)
\tWRITE (dl) "x"
\tw = IOSTAT(dl)
\tFDELETE (dl) "{spec}"
\td = IOSTAT(dl)
""").globals
    assert g["r"] == g["a"] == g["d"] == E.ILLEGAL_FILE_NAME and g["w"] == E.NOT_OPEN
    assert outside.read_text() == "keep"


def test_a_file_open_for_write_in_one_task_cannot_be_opened_in_another(tmp_path):
    emu = Emulator.from_source(
        ".PROGRAM w()\n\tATTACH (dl, 4) \"DISK\"\n\tFOPENW (dl) \"a.txt\"\n\tWAIT go\n\tFCLOSE (dl)\n.END\n"
        ".PROGRAM r()\n\tATTACH (dl, 4) \"DISK\"\n\tFOPENR (dl) \"a.txt\"\n\tbusy = IOSTAT(dl)\n\tgo = TRUE\n"
        "\tWAIT TASK(1, 1) <> 4\n\tFOPENR (dl) \"a.txt\"\n\tfree = IOSTAT(dl)\n.END\n",
        filename="d.V2", strict=True, robot=False, disk_dir=tmp_path)
    emu.globals["go"] = 0
    emu.execute(1, "w")
    emu.call("r", task=2)
    assert emu.globals["busy"] == E.FILE_IN_USE and emu.globals["free"] == 1


def test_the_default_disk_is_a_temporary_folder_of_its_own(tmp_path):
    a = Emulator.from_source(".PROGRAM t()\n.END\n", robot=False)
    b = Emulator.from_source(".PROGRAM t()\n.END\n", robot=False)
    assert a.disk_dir.is_dir() and b.disk_dir.is_dir() and a.disk_dir != b.disk_dir
