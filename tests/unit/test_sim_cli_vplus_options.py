"""`aioadept sim --vplus` refuses the Python server's own options (the V+ program serves the connections there, so
they would be ignored silently), in one line that names the option and where its V+ counterpart lives."""

from __future__ import annotations

import pytest

from aioadept.cli.sim import main

VPLUS = ["--vplus", "vplus/rserver.V2", "vplus/rsskills.V2", "vplus/rsconfig.V2", "--run", "rs.main"]


@pytest.mark.parametrize(("option", "where"), [
    (["--max-clients", "4"], "rs.maxcli"),
    (["--max-queued", "10"], "rs.maxq"),
    (["--allow", "127.0.0.1"], "address"),
    (["--line-timeout", "3"], "rs.lntmo"),
    (["--stop-window", "2"], "rs.stmo"),
    (["--stop-port", "2000"], "rs.sport"),
])
def test_a_python_server_option_with_vplus_is_one_line_and_exit_2(capsys, option, where):
    with pytest.raises(SystemExit) as info:
        main([*VPLUS, *option])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith(f"aioadept sim: error: {option[0]} is an option of the Python sim's server") and where in err
