"""Who may join a Zenoh cell (docs/security.md, "Zenoh"): a Zenoh configuration file (``--zenoh-config``, ``[bus]
zenoh_config``) with Zenoh's own user/password authentication. Real processes on 127.0.0.1: ``aioadept sim`` is the
router and requires credentials; a node with the right ones joins and follows the arm, one without them or with
wrong ones is refused (exit 1, one line); a cell file's relative ``zenoh_config`` is read beside the file; whatever
the file says, multicast scouting and gossip stay off. Each test has a hard time cap."""

from __future__ import annotations

import asyncio
import importlib.util
import os
import subprocess
import sys
import textwrap

import pytest

from aioadept.ports import free_port
from aioadept.testing.nodes import running_node

pytestmark = pytest.mark.skipif(importlib.util.find_spec("zenoh") is None,
                                reason="the [zenoh] extra (eclipse-zenoh) is not installed")

AIOADEPT = [sys.executable, "-m", "aioadept"]


def write_files(d) -> dict[str, str]:
    """The router's file (who may connect; it also asks for multicast scouting, which must stay off) and the
    clients' (right and wrong password)."""
    (d / "users.txt").write_text("cellnode:s3cret\n")
    files = {
        "router": "{ transport: { auth: { usrpwd: { dictionary_file: \"%s\" } } },\n"
                  "  scouting: { multicast: { enabled: true }, gossip: { enabled: true } } }\n" % (d / "users.txt"),
        "good": '{ transport: { auth: { usrpwd: { user: "cellnode", password: "s3cret" } } } }\n',
        "bad": '{ transport: { auth: { usrpwd: { user: "cellnode", password: "guess" } } } }\n',
    }
    out = {}
    for name, text in files.items():
        (d / f"{name}.json5").write_text(text)
        out[name] = str(d / f"{name}.json5")
    return out


FOLLOW = textwrap.dedent("""
    import asyncio, sys
    from aioadept.bus import zenoh as zb
    from aioadept.bus.messages import ROBOT_STATE_TOPIC, RobotState
    from aioadept.bus.pubsub import Subscriber
    zb.configure(zb.ZenohOptions.client(sys.argv[1], config_file=sys.argv[2] if sys.argv[2] != "-" else None))
    async def main():
        async with Subscriber(sys.argv[3], topics=[ROBOT_STATE_TOPIC]) as sub:
            _, payload = await asyncio.wait_for(sub.recv(), 10)
        print("joints", *RobotState.from_bytes(payload).joints_deg)
    try:
        asyncio.run(main())
    except Exception as exc:
        print(f"follow: {exc}", file=sys.stderr); sys.exit(1)
""")


@pytest.mark.timeout(60)
async def test_only_a_node_with_the_cells_credentials_joins(tmp_path) -> None:
    files = write_files(tmp_path)
    router = f"tcp/127.0.0.1:{free_port()}"
    cell = f"acl{os.getpid()}"
    async with running_node("sim", "--port", "0", "--joints", "10,-90,180,0,90,0", "--transport", "zenoh",
                            "--zenoh-listen", router, "--zenoh-config", files["router"], "--cell", cell,
                            log_path=tmp_path / "sim.log") as sim:
        key = sim.ready["state"]
        assert key == f"zenoh:aioadept/{cell}/sim/state"

        async def follow(config: str) -> subprocess.CompletedProcess:
            return await asyncio.to_thread(subprocess.run, [sys.executable, "-c", FOLLOW, router, config, key],
                                           capture_output=True, text=True, timeout=30)

        ok, wrong, none = await asyncio.gather(follow(files["good"]), follow(files["bad"]), follow("-"))
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.split()[:2] == ["joints", "10.0"]
    for res in (wrong, none):
        assert res.returncode == 1 and res.stdout == ""
        assert "cannot open the Zenoh session" in res.stderr and len(res.stderr.strip().splitlines()) == 1


@pytest.mark.timeout(60)
async def test_a_cell_files_zenoh_config_is_read_beside_the_file(tmp_path) -> None:
    files = write_files(tmp_path)
    router = f"tcp/127.0.0.1:{free_port()}"
    cell = f"aclf{os.getpid()}"
    (tmp_path / "cell").mkdir()
    (tmp_path / "cell" / "good.json5").write_text((tmp_path / "good.json5").read_text())
    cell_file = tmp_path / "cell" / "cell.toml"
    cell_file.write_text(f'[vision]\nstart = false\n[bus]\ntransport = "zenoh"\ncell = "{cell}"\n'
                         f'zenoh_router = "{router}"\nstart_router = false\nzenoh_config = "good.json5"\n')
    async with running_node("sim", "--port", "0", "--transport", "zenoh", "--zenoh-listen", router,
                            "--zenoh-config", files["router"], "--cell", cell, "--state-endpoint", "none",
                            log_path=tmp_path / "sim.log"):
        # from another folder: the file's relative path is the file's neighbour, not the working directory's
        async with running_node("vision", "--config", str(cell_file), log_path=tmp_path / "vision.log") as vision:
            assert vision.ready["request"] == f"zenoh:aioadept/{cell}/vision/request"
        cell_file.write_text(cell_file.read_text().replace('zenoh_config = "good.json5"\n', ""))
        res = await asyncio.to_thread(subprocess.run, [*AIOADEPT, "vision", "--config", str(cell_file)],
                                      capture_output=True, text=True, timeout=30)
    # refused by the router: a bus the node cannot reach, exit 1 as sim and state (not a usage mistake)
    assert res.returncode == 1 and "cannot open the Zenoh session" in res.stderr, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1, res.stderr


@pytest.mark.timeout(30)
@pytest.mark.parametrize("how", ["option", "file"])
def test_a_missing_or_broken_zenoh_config_is_one_line_before_anything_starts(tmp_path, how) -> None:
    broken = tmp_path / "broken.json5"
    broken.write_text("{ transport: ")
    for path, says in ((tmp_path / "none.json5", "No such file"), (broken, str(broken))):
        if how == "option":
            argv = ["sim", "--transport", "zenoh", "--zenoh-config", str(path)]
        else:
            cell_file = tmp_path / "cell.toml"
            cell_file.write_text(f'[bus]\ntransport = "zenoh"\nzenoh_config = "{path.name}"\n')
            argv = ["sim", "--config", str(cell_file)]
        res = subprocess.run([*AIOADEPT, *argv], capture_output=True, text=True, timeout=20)
        lines = res.stderr.strip().splitlines()
        assert res.returncode == 2 and len(lines) == 1, res.stderr
        assert "Zenoh config file" in lines[0] and says in lines[0]
        if how == "file":
            assert "zenoh_config" in lines[0] and "cell.toml" in lines[0]


def test_the_file_cannot_turn_scouting_back_on(tmp_path) -> None:
    from aioadept.bus import zenoh as zb

    files = write_files(tmp_path)
    cfg = zb.ZenohOptions.router("tcp/127.0.0.1:7999", config_file=files["router"]).config()
    assert cfg.get_json("scouting/multicast/enabled") == "false"
    assert cfg.get_json("scouting/gossip/enabled") == "false"
    assert cfg.get_json("listen/endpoints") == '["tcp/127.0.0.1:7999"]'
    assert str(tmp_path / "users.txt") in cfg.get_json("transport/auth/usrpwd/dictionary_file")
