"""Who may command the cell from OPC UA: the users file (``NAME:PASSWORD`` lines, owner-only) and the password
check (aioadept.opcua.commands)."""

from __future__ import annotations

import pytest

from aioadept.opcua.commands import password_ok, read_users


def users_file(tmp_path, text: str, mode: int = 0o600):
    p = tmp_path / "users"
    p.write_text(text)
    p.chmod(mode)
    return p


def test_the_users_file_gives_names_and_passwords_and_skips_comments(tmp_path) -> None:
    users = read_users(users_file(tmp_path, "# operators\n\noperator:s3cret: with colon \nshift2:pw\n"))
    assert users == {"operator": "s3cret: with colon", "shift2": "pw"}
    assert password_ok(users, "operator", "s3cret: with colon")
    assert password_ok(users, "shift2", b"pw")
    assert not password_ok(users, "shift2", "PW")
    assert not password_ok(users, "nobody", "pw")
    assert not password_ok(users, None, None)


@pytest.mark.parametrize("text, mode, says", [
    ("operator:pw\n", 0o644, "readable by others"),
    ("operator:pw\n", 0o640, "chmod 600"),
    ("operator\n", 0o600, ":1: expected NAME:PASSWORD"),
    ("a:1\n:2\n", 0o600, ":2: expected NAME:PASSWORD"),
    ("a:1\nb:\n", 0o600, ":2: expected NAME:PASSWORD"),
    ("a:1\na:2\n", 0o600, ":2: user 'a' given twice"),
    ("# nobody\n", 0o600, "no user"),
])
def test_a_bad_users_file_is_refused_naming_the_file_and_line(tmp_path, text: str, mode: int, says: str) -> None:
    p = users_file(tmp_path, text, mode)
    with pytest.raises(ValueError, match=str(p)) as err:
        read_users(p)
    assert says in str(err.value)
